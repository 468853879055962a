"""Stream clocks that disagree: the offsets a recording's stamps hide.

Each sensor stream carries its own clock. A PMU in UTC beside PT/CT in local time, or a
recorder whose clock is a few seconds off, puts the same disturbance at different stamps in
different streams; aligned on the stamps, the windows then mix moments that did not happen
together, and every parameter they give is wrong. Two checks, both on the recording as read:

- :func:`clock_offsets`: a stream whose stamps meet no other stream's at all (hours off);
- :func:`pmu_lag_s`: the lag between the rotor angle's rate (PMU) and the speed (encoder),
  which dδ/dt = ω_s (ω − 1) ties together at every instant, and :func:`pt_ct_lag_s`: the
  electrical power (PT/CT) against the speed's rate, tied by the swing equation; each found by
  cross-correlation over the recording's swings. A lag of tens of milliseconds is a sensor
  latency (the diagnosis names it, ``sensor_delay``); one of half a second or more is a clock
  offset.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from phid_ros.io.recording import Recording
from phid_ros.model.conventions import NS, omega_s
from phid_ros.numerics import lowpass2

GRID_HZ = 100.0  # the swing band is below 3 Hz
MAX_LAG_S = 10.0
LOOK_S = 1800.0  # the first half hour is enough to find a constant offset, and bounds the work
MIN_CORRELATION = 0.7
CLOCK_OFFSET_S = 0.5  # shorter lags are latencies, the diagnosis's business


def clock_offsets(rec: Recording, reference: str = "pt_ct") -> list[str]:
    """Streams whose stamps do not overlap the reference stream's at all: a clock set to another
    time zone (UTC against local time), or another day. Aligned on their stamps, such streams
    meet no other data and the recording shows no disturbance; the problem is named instead."""
    ref = rec.streams.get(reference)
    if ref is None or not len(ref):
        return []
    r0, r1 = int(ref.t_ns[0]), int(ref.t_ns[-1])
    out = []
    for name, s in rec.streams.items():
        if name == reference or not len(s):
            continue
        s0, s1 = int(s.t_ns[0]), int(s.t_ns[-1])
        if s1 < r0 or s0 > r1:
            offset = (s0 - r0) / NS
            hours = offset / 3600.0
            hint = " (a whole number of hours: UTC against local time?)" if abs(hours - round(hours)) < 0.01 else ""
            out.append(
                f"the {name} stream's stamps do not overlap the {reference} stream's: they start {offset:+.1f} s "
                f"from them{hint}; correct the clock of one of them"
            )
    return out


def pmu_lag_s(rec: Recording, f_nominal_hz: float) -> float:
    """How much later the PMU stamps a swing than the encoder does (s); NaN when the recording
    cannot tell (no rotor angle or speed, no swing, no clear peak). dδ/dt = ω_s (ω − 1)."""
    w_s = omega_s(f_nominal_hz)
    return _lag(
        rec,
        ("encoder", "omega", lambda w, dt: w_s * (w - 1.0)),
        ("pmu", "delta", lambda d, dt: np.gradient(np.unwrap(d), dt)),
        lambda v, dt: lowpass2(v - np.mean(v), 2.0, dt),
    )


def pt_ct_lag_s(rec: Recording) -> float:
    """How much later PT/CT stamps a swing than the encoder does (s), as :func:`pmu_lag_s`.

    By the swing equation 2H dω/dt = P_m − P_e − D (ω − 1), the electrical power's swings
    are the speed's rate's, turned over; in the swing band (0.3-3 Hz, where the slow P_m
    steps and the noise are not) they correlate at 0.92 on the catalogue.
    """

    def band(v: np.ndarray, dt: float) -> np.ndarray:
        v = v - np.mean(v)
        return lowpass2(v, 3.0, dt) - lowpass2(v, 0.3, dt)

    return _lag(
        rec,
        ("encoder", "omega", lambda w, dt: np.gradient(w, dt)),
        ("pt_ct", "p_e", lambda p, dt: -p),
        band,
    )


Signal = tuple[str, str, Callable[[np.ndarray, float], np.ndarray]]  # stream, channel, what of it


def _lag(rec: Recording, x_of: Signal, y_of: Signal, shape: Callable[[np.ndarray, float], np.ndarray]) -> float:
    """The lag of ``y_of``'s stream behind ``x_of``'s (s) at the peak of their cross-correlation
    on a common 100 Hz grid over the first LOOK_S, both shaped by ``shape``; NaN when either
    channel is missing, the overlap is short, or the peak is not clear."""
    found = []
    for stream, channel, _ in (x_of, y_of):
        s = rec.streams.get(stream)
        if s is None or channel not in s.channels:
            return math.nan
        t, v = _finite(s.t_ns, s.channels[channel])
        if len(t) < 100:
            return math.nan
        found.append((t, v))
    (t_x, x_raw), (t_y, y_raw) = found
    t0, t1 = max(t_x[0], t_y[0]), min(t_x[-1], t_y[-1])
    t1 = min(t1, t0 + int(LOOK_S * NS))
    dt = 1.0 / GRID_HZ
    grid = np.arange(t0, t1, int(dt * NS), dtype=np.int64)
    lags = min(int(MAX_LAG_S * GRID_HZ), len(grid) // 4)  # a short recording: shorter offsets only
    if lags < GRID_HZ:
        return math.nan
    x = shape(x_of[2](np.interp(grid, t_x, x_raw), dt), dt)
    y = shape(y_of[2](np.interp(grid, t_y, y_raw), dt), dt)
    n = 1 << int(math.ceil(math.log2(2 * len(grid))))
    r = np.fft.irfft(np.conj(np.fft.rfft(x, n)) * np.fft.rfft(y, n), n)
    r = np.concatenate((r[-lags:], r[: lags + 1])) / (np.linalg.norm(x) * np.linalg.norm(y) or 1.0)
    k = int(np.argmax(r))
    if r[k] < MIN_CORRELATION:
        return math.nan
    return (k - lags) * dt


def _finite(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ok = np.isfinite(x)
    return t[ok], x[ok]


def clock_problems(rec: Recording) -> list[str]:
    """Every check, as one-line problems (empty when the clocks agree as far as can be told)."""
    out = clock_offsets(rec)
    if out:
        return out
    lags = (
        ("pmu", pmu_lag_s(rec, rec.f_nominal_hz), "dδ/dt against ω"),
        ("pt_ct", pt_ct_lag_s(rec), "P_e against dω/dt"),
    )
    off = [lag for _, lag, _ in lags if math.isfinite(lag) and abs(lag) >= CLOCK_OFFSET_S]
    if len(off) == 2 and abs(off[0] - off[1]) <= 2.0 / GRID_HZ:  # both others agree: the encoder is the odd one
        return [
            f"the encoder stream stamps the rotor's swings {abs(off[0]):.2f} s {'before' if off[0] > 0 else 'after'} "
            "both the pmu and the pt_ct streams do (cross-correlated): a clock offset of the encoder; correct it"
        ]
    for stream, lag, what in lags:
        if math.isfinite(lag) and abs(lag) >= CLOCK_OFFSET_S:
            out.append(
                f"the {stream} stream stamps the rotor's swings {abs(lag):.2f} s {'after' if lag > 0 else 'before'} "
                f"the encoder does ({what}, cross-correlated): a clock offset; correct the clock of one of them"
            )
    return out
