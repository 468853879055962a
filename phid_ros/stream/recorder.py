"""A recorder's own channels beside the sensor streams: kept as they came, put on a window's stamps.

An excitation controller records the field current, the regulator's output and the stabiliser's
(:data:`phid_ros.io.topics.RECORDER_STREAMS`). They are not the aligned grid's channels: nothing
on line waits for them, a deployment without them loses nothing. But they are what determines
X_d, X'_d and T'_d0 on a recorder without the rotor's channels (the field circuit,
:mod:`phid_ros.ident.field_circuit`), so the online pipeline keeps the last ``ring_seconds`` of
them and hands each event window its share, on the window's own stamps, by the very rule
``phid identify`` uses for a recording's scenarios (:func:`on_stamps`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from phid_ros.io.topics import RECORDER_CHANNELS, RECORDER_STREAMS
from phid_ros.model.conventions import NS
from phid_ros.stream.align import StreamHealth
from phid_ros.stream.ring import RingBuffer

Array = NDArray[np.float64]


def on_stamps(
    ts: NDArray[np.int64], channels: Mapping[str, Array], period_ns: int, t_ns: NDArray[np.int64]
) -> dict[str, Array]:
    """A recorder's samples (stamps ``ts`` in order, ``period_ns`` apart where unbroken) on the
    stamps ``t_ns``: each the recorded one at that stamp, or linear between two neighbours at
    most 1.5 periods apart; NaN elsewhere (outside the stream, across its gaps). Only channels
    with a finite sample come out."""
    out: dict[str, Array] = {}
    if not len(ts) or not len(t_ns):
        return out
    k = np.clip(np.searchsorted(ts, t_ns, side="right") - 1, 0, len(ts) - 1)
    k1 = np.minimum(k + 1, len(ts) - 1)
    span = (ts[k1] - ts[k]).astype(np.float64)
    inside = (t_ns >= ts[k]) & (t_ns <= ts[k1]) & (span <= 1.5 * period_ns)
    inside |= t_ns == ts[k]
    w = np.where(span > 0, (t_ns - ts[k]) / np.where(span > 0, span, 1.0), 0.0)
    for c, x in channels.items():
        on = np.where(inside, x[k] + w * (x[k1] - x[k]), np.nan)
        if np.isfinite(on).any():
            out[c] = on
    return out


class RecorderBuffer:
    """The last ``seconds`` of the recorder's streams, each sample as stamped, and their health.

    Samples out of order or on a stamp already taken are dropped and counted (as the aligner
    does), so the kept stamps increase and a window finds its share by binary search."""

    def __init__(self, seconds: float, *, not_recorded: frozenset[str] = frozenset()) -> None:
        self.seconds = seconds
        self._ring: RingBuffer | None = None  # sized on the first message, by the recorder's own rate
        self.health = {s.name: StreamHealth(s.name) for s in RECORDER_STREAMS}
        for s in RECORDER_STREAMS:
            self.health[s.name].not_recorded = all(c in not_recorded for c in s.channels)
        self.period_ns = 0

    def ingest(
        self,
        stream: str,
        t0_ns: int,
        period_ns: int,
        arrays: Mapping[str, Array],
        receive_ns: int | None = None,
    ) -> None:
        h = self.health[stream]
        n = max((len(a) for a in arrays.values()), default=0)
        h.messages += 1
        h.samples += n
        if n == 0:
            return
        if any(len(a) != n for a in arrays.values()):
            h.malformed += n  # which array lost which value is unknown: none of it placed
            return
        if int(t0_ns) == 0:
            h.zero_stamps += n  # an unset clock, not a time
            return
        if self._ring is None:
            self.period_ns = int(period_ns)
            h.expected_rate_hz = NS / period_ns if period_ns > 0 else h.expected_rate_hz
            self._ring = RingBuffer(max(1, int(self.seconds * NS // max(1, period_ns))), RECORDER_CHANNELS, period_ns)
        t = int(t0_ns) + np.arange(n, dtype=np.int64) * int(period_ns)
        values = np.full((n, len(RECORDER_CHANNELS)), np.nan)
        for j, c in enumerate(RECORDER_CHANNELS):
            if c in arrays:
                values[:, j] = arrays[c]
        last = h.last_stamp_ns
        if last is not None:
            late = t <= last
            if late.any():
                h.out_of_order += int(late.sum())
                t, values = t[~late], values[~late]
                if not len(t):
                    return
            hole = int(t[0]) - last
            if hole > 1.5 * period_ns:
                h.note_gap(last, int(t[0]), int(round(hole / period_ns)) - 1)
        if receive_ns is not None:
            h.last_receive_ns = int(receive_ns)
            h.lag_ns = int(receive_ns) - int(t[-1])
        h.accepted += len(t)
        h.last_stamp_ns = int(t[-1])
        h.note_block(int(t[-1]), len(t))
        self._ring.append(t, values)

    def columns(self, t_ns: NDArray[np.int64]) -> dict[str, Array]:
        """The recorder's channels on ``t_ns`` (a window's stamps); {} when it has none there."""
        if self._ring is None or not len(t_ns):
            return {}
        ts, x = self._ring.window(int(t_ns[0]) - 2 * self.period_ns, int(t_ns[-1]) + 2 * self.period_ns)
        return on_stamps(ts, {c: x[:, j] for j, c in enumerate(RECORDER_CHANNELS)}, self.period_ns, t_ns)

    def clear(self) -> None:
        """A new segment (the clock jumped): nothing kept belongs to the windows after it."""
        if self._ring is not None:
            self._ring.clear()
        for h in self.health.values():
            h.last_stamp_ns = None
            h.forget_blocks()
