"""Stream clocks that disagree: the offsets a recording's stamps hide.

Each sensor stream carries its own clock. A PMU in UTC beside PT/CT in local time, or a
recorder whose clock is a few seconds off, puts the same disturbance at different stamps in
different streams; aligned on the stamps, the windows then mix moments that did not happen
together, and every parameter they give is wrong. Two checks, both on the recording as read:

- :func:`clock_offsets`: a stream whose stamps meet no other stream's at all (hours off);
- :func:`pmu_lag_s`: the lag between the rotor angle's rate (PMU) and the speed (encoder),
  which dδ/dt = ω_s (ω − 1) ties together at every instant: found by cross-correlation over
  the recording's swings. A lag of tens of milliseconds is a sensor latency (the diagnosis
  names it, ``sensor_delay``); one of half a second or more is a clock offset.
"""

from __future__ import annotations

import math

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
    cannot tell (no rotor angle or speed, no swing, no clear peak)."""
    enc, pmu = rec.streams.get("encoder"), rec.streams.get("pmu")
    if enc is None or pmu is None or "omega" not in enc.channels or "delta" not in pmu.channels:
        return math.nan
    t_w, w = _finite(enc.t_ns, enc.channels["omega"])
    t_d, d = _finite(pmu.t_ns, pmu.channels["delta"])
    if len(t_w) < 100 or len(t_d) < 100:
        return math.nan
    t0, t1 = max(t_w[0], t_d[0]), min(t_w[-1], t_d[-1])
    t1 = min(t1, t0 + int(LOOK_S * NS))
    dt = 1.0 / GRID_HZ
    grid = np.arange(t0, t1, int(dt * NS), dtype=np.int64)
    lags = min(int(MAX_LAG_S * GRID_HZ), len(grid) // 4)  # a short recording: shorter offsets only
    if lags < GRID_HZ:
        return math.nan
    x = omega_s(f_nominal_hz) * (np.interp(grid, t_w, w) - 1.0)
    y = np.gradient(np.interp(grid, t_d, np.unwrap(d)), dt)
    x, y = (lowpass2(v - np.mean(v), 2.0, dt) for v in (x, y))
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
    """Both checks, as one-line problems (empty when the clocks agree as far as can be told)."""
    out = clock_offsets(rec)
    if out:
        return out
    lag = pmu_lag_s(rec, rec.f_nominal_hz)
    if math.isfinite(lag) and abs(lag) >= CLOCK_OFFSET_S:
        out.append(
            f"the pmu stream stamps the rotor's swings {abs(lag):.2f} s {'after' if lag > 0 else 'before'} the "
            "encoder does (dδ/dt against ω, cross-correlated): a clock offset; correct the clock of one of them"
        )
    return out
