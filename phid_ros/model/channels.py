"""The measured channels, their column in a frame, their plausible ranges, and the frame itself.

A :class:`Frame` is the one container of samples from the aligner on: stamps, one row per
sample over every channel in ``CHANNELS`` order, and the sample period. The aligner emits
frames (``AlignedBlock``), the ring buffer hands them out, an event window is one, the store
serialises one, and a scenario views one's columns by name.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

CHANNELS: tuple[str, ...] = ("v_t", "theta_t", "i_d", "i_q", "omega", "delta", "v_f", "p_m", "p_e", "q_e")
CHANNEL_INDEX: dict[str, int] = {c: i for i, c in enumerate(CHANNELS)}  # column of a channel in a frame
# sample periods closer than this are one rate: a jittered clock resampled onto its mean period
# (a trend log's) differs from another file's by nanoseconds
SAME_PERIOD = 1e-4


def channel_columns(values: Any) -> dict[str, Any]:
    """The columns of a (samples x CHANNELS) matrix by channel name (views, no copies)."""
    return {c: values[:, i] for i, c in enumerate(CHANNELS)}


@dataclass
class Frame:
    t_ns: NDArray[np.int64]  # (n,) increasing
    values: NDArray[np.float64]  # (n, len(CHANNELS)); NaN where a stream had a gap
    period_ns: int

    def __len__(self) -> int:
        return len(self.t_ns)

    def __iter__(self) -> Iterator[Any]:
        """A frame unpacks as ``t_ns, values``."""
        return iter((self.t_ns, self.values))

    def channel(self, name: str) -> NDArray[np.float64]:
        return self.values[:, CHANNEL_INDEX[name]]

    def columns(self) -> dict[str, NDArray[np.float64]]:
        return channel_columns(self.values)

    @classmethod
    def of_columns(cls, columns: Mapping[str, Any], period_ns: int, start_ns: int = 0) -> Frame:
        """A frame from one array per channel (a simulation's or a test's), stamped every
        ``period_ns`` from ``start_ns``. Column-major, so each channel stays contiguous."""
        missing = [c for c in CHANNELS if c not in columns]
        if missing:
            raise KeyError(f"missing channel(s) {missing}")
        n = len(columns[CHANNELS[0]])
        values = np.empty((n, len(CHANNELS)), order="F")
        for i, c in enumerate(CHANNELS):
            values[:, i] = columns[c]
        return cls(start_ns + np.arange(n, dtype=np.int64) * int(period_ns), values, int(period_ns))

    def rows(self, a: int, b: int) -> Frame:
        """Samples a to b (exclusive), as views."""
        return Frame(self.t_ns[a:b], self.values[a:b], self.period_ns)

    def between(self, t0_ns: int, t1_ns: int) -> Frame:
        """The samples with t0 <= t <= t1, as views."""
        a = int(np.searchsorted(self.t_ns, t0_ns, side="left"))
        b = int(np.searchsorted(self.t_ns, t1_ns, side="right"))
        return self.rows(a, b)


# Plausible ranges in per unit / rad on the machine base: anything outside is a wrong feed (a kV, MW
# or A signal by mistake), not a disturbance. One table for replay, identify and import-csv.
PLAUSIBLE: dict[str, tuple[float, float]] = {
    "v_t": (0.0, 3.0),
    "i_d": (-25.0, 25.0),
    "i_q": (-25.0, 25.0),
    "p_e": (-25.0, 25.0),
    "q_e": (-25.0, 25.0),
    "omega": (0.5, 1.5),
    "p_m": (-5.0, 5.0),
    "theta_t": (-1e6, 1e6),
    "delta": (-1e6, 1e6),
    "v_f": (-30.0, 30.0),
    # a recorder's, beside the channels (:data:`phid_ros.io.topics.RECORDER_STREAMS`): the field
    # current as v_f, the regulator's and the stabiliser's outputs in the controller's own units
    "i_fd": (-30.0, 30.0),
    "v_r": (-100.0, 100.0),
    "v_s": (-10.0, 10.0),
    "v_ref": (0.0, 3.0),  # the regulator's set-point, pu of the rated terminal voltage
}

# What a channel's typical magnitude says it was recorded in, when it is not per unit.
_UNIT_GUESSES: dict[str, tuple[tuple[float, float, str], ...]] = {
    "v_t": ((3.0, 1000.0, "kV: divide by the machine's rated kV"), (1000.0, 1e7, "V: divide by the rated voltage")),
    "i_d": ((25.0, 1e7, "A or kA: divide by the rated current"),),
    "i_q": ((25.0, 1e7, "A or kA: divide by the rated current"),),
    "p_e": ((25.0, 1e7, "MW: divide by the machine's MVA base"),),
    "q_e": ((25.0, 1e7, "Mvar: divide by the machine's MVA base"),),
    "p_m": ((5.0, 1e7, "MW: divide by the machine's MVA base"),),
    "omega": (
        (40.0, 70.0, "Hz: divide by the nominal frequency"),
        (250.0, 400.0, "rad/s: divide by 2π times the nominal frequency"),
        (400.0, 4000.0, "rpm: divide by the synchronous speed"),
    ),
    "v_f": ((30.0, 1e7, "V: divide by the field voltage base"),),
    "i_fd": ((30.0, 1e7, "A: divide by the field current base"),),
}


def unit_problem(channel: str, values: object, *, share: float = 0.5) -> str | None:
    """Why ``values`` of ``channel`` are not per unit (with a guess at their unit), or None.

    A channel is refused when at least ``share`` of its finite samples lie outside its
    plausible per-unit range; isolated wild samples are the aligner's business (dropped, counted).
    """
    import numpy as np

    x = np.asarray(values, dtype=float)
    lo, hi = PLAUSIBLE[channel]
    # counted without gathering the finite samples (a copy of the channel): NaN compares false,
    # and an infinite sample, outside any range, is taken out of both counts
    infinite = int(np.count_nonzero(np.isinf(x)))
    finite = x.size - infinite - int(np.count_nonzero(np.isnan(x)))
    if finite == 0:
        return None
    outside = (int(np.count_nonzero((x < lo) | (x > hi))) - infinite) / finite
    if outside < share:
        return None
    x = x[np.isfinite(x)]
    typical = float(np.median(np.abs(x)))
    guess = next((text for a, b, text in _UNIT_GUESSES.get(channel, ()) if a <= typical < b), None)
    what = f"looks like {guess}" if guess else "not per unit on the machine base"
    return (
        f"channel {channel}: {100 * outside:.0f} % of samples outside the per-unit range {lo:g} to {hi:g} "
        f"(typical magnitude {typical:.4g}): {what}"
    )


# pu: a machine with less stator current than this is at no load (an open-circuit test); one
# threshold for the importer's field calibration and the identification's no-load routes
NO_LOAD_CURRENT = 0.02


def current_of(signals: Mapping[str, Any]) -> NDArray[np.float64]:
    """|I| = |P + jQ| / V_t, sample by sample."""
    return np.asarray(np.hypot(signals["p_e"], signals["q_e"]) / np.maximum(signals["v_t"], 1e-6), dtype=np.float64)
