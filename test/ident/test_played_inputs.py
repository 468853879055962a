"""The play-in's V_t and theta_t: the sensor noise taken out between switching instants, nothing else."""

from __future__ import annotations

import numpy as np

from phid_ros.ident.played_inputs import CUTOFF_HZ, smoothed_angle
from phid_ros.ident.played_inputs import smoothed as smoothed_at

DT = 1e-3  # a 1 kHz recorder


def smoothed(x: np.ndarray, dt: float, switching: list[int]) -> np.ndarray:
    return smoothed_at(x, dt, switching, CUTOFF_HZ)


def _fault_voltage() -> tuple[np.ndarray, list[int]]:
    """V_t through a 100 ms fault: a drop to 0.2 at 1 s, decaying 30 ms and 1.2 s modes, a jump back."""
    t = np.arange(0, 4.0, DT)
    v = np.ones_like(t)
    on = (t >= 1.0) & (t < 1.1)
    v[on] = 0.2 + 0.15 * np.exp(-(t[on] - 1.0) / 0.03)
    after = t >= 1.1
    ta = t[after] - 1.1
    v[after] = 1.0 - 0.12 * np.exp(-ta / 0.03) - 0.05 * np.exp(-ta / 1.2) * np.cos(2 * np.pi * 1.3 * ta)
    return v, [1000, 1100]


def test_the_noise_on_the_played_in_voltage_falls_to_a_third() -> None:
    v, switching = _fault_voltage()
    rng = np.random.default_rng(3)
    noise = 0.002 * rng.standard_normal(v.size)
    out = smoothed(v + noise, DT, switching)
    assert np.std(out - v) < 0.36 * 0.002  # 60 Hz of a 500 Hz band, 4th order: about 0.33
    # the signal itself (a damper's 30 ms mode of 0.15 pu, the swing) is left: within 0.15 % of
    # that mode at a segment's first samples (the odd extension's curvature error), a seventh of the noise
    assert np.max(np.abs(smoothed(v, DT, switching) - v)) < 3e-4


def test_a_step_is_not_smeared_across_its_switching_instant() -> None:
    v, switching = _fault_voltage()
    out = smoothed(v, DT, switching)
    for k in switching:
        assert abs(out[k - 1] - v[k - 1]) < 3e-4 and abs(out[k] - v[k]) < 3e-4
    # the recorder's jump a sample late: the segment starts at the jump, not at the label
    late = np.concatenate([v[:1], v[:-1]])
    out = smoothed(late, DT, [1000, 1100])
    assert abs(out[1000] - 1.0) < 3e-4 and abs(out[1001] - late[1001]) < 3e-4
    # a PMU's angle 20 ms behind the PT the instants were found on: its jump starts its segment
    lagged = np.concatenate([np.full(20, v[0]), v[:-20]])
    out = smoothed(lagged, DT, [1000, 1100])
    assert np.max(np.abs(out - lagged)) < 3e-4


def test_a_slow_recorder_a_short_segment_and_an_absent_channel_are_played_in_as_measured() -> None:
    v, _ = _fault_voltage()
    pmu = v[::20] + 0.002  # 50 reports/s: no band above the cut-off to take out
    assert np.array_equal(smoothed(pmu, 0.02, [50, 55]), pmu)
    short = v[990:1020].copy()  # ten samples before the event, twenty after
    assert np.array_equal(smoothed(short, DT, [10]), short)
    absent = np.full(4000, np.nan)
    assert np.array_equal(smoothed(absent, DT, [1000]), absent, equal_nan=True)


def test_an_angle_that_wraps_inside_a_segment_is_smoothed_across_the_wrap() -> None:
    """A recorder's angle jumping by 2 pi in mid-segment: without unwrapping, a dozen samples
    around the jump came out anywhere between -pi and pi. Each sample keeps its recorded branch."""
    t = np.arange(0, 4.0, DT)
    theta = 3.0 + 0.4 * t  # passes pi at 0.35 s
    wrapped = np.angle(np.exp(1j * theta))
    rng = np.random.default_rng(5)
    noise = 0.001 * rng.standard_normal(t.size)
    out = smoothed_angle(wrapped + noise, DT, [1000], CUTOFF_HZ)
    reference = smoothed(theta + noise, DT, [1000])
    assert np.max(np.abs(np.angle(np.exp(1j * (out - reference))))) < 1e-9
    assert np.max(np.abs(out - (wrapped + noise))) < 0.01  # the branch of each sample kept
