import numpy as np

from phid_ros.model.channels import CHANNELS
from phid_ros.stream.detector import Detector, DetectorSettings
from phid_ros.stream.ring import RingBuffer

MS = 1_000_000


def _quiet(n, seed=0):
    rng = np.random.default_rng(seed)
    x = np.zeros((n, len(CHANNELS)))
    x[:, CHANNELS.index("v_t")] = 1.0 + rng.normal(0, 0.002, n)
    x[:, CHANNELS.index("p_m")] = 0.8 + rng.normal(0, 0.002, n)
    x[:, CHANNELS.index("omega")] = 1.0
    return x


def test_no_false_events_in_noisy_quiet_data():
    ring = RingBuffer(120_000, CHANNELS)
    det = Detector(ring, MS)
    x = _quiet(100_000)
    found = []
    for k in range(0, 100_000, 500):
        ring.append(np.arange(k, k + 500, dtype=np.int64) * MS, x[k : k + 500])
        found += det.update()[0]
    assert found == []


def test_a_gap_in_the_data_makes_the_window_stale_not_wrong():
    ring = RingBuffer(120_000, CHANNELS)
    det = Detector(ring, MS, DetectorSettings(post_s=5.0))
    x = _quiet(20_000)
    x[5000:, CHANNELS.index("p_m")] += 0.1  # a torque step at 5 s
    x[7000:7100, CHANNELS.index("omega")] = np.nan  # the encoder stalls for 0.1 s
    events, windows = [], []
    for k in range(0, 20_000, 1000):
        ring.append(np.arange(k, k + 1000, dtype=np.int64) * MS, x[k : k + 1000])
        e, w = det.update()
        events += e
        windows += w
    assert [e.kind for e in events] == ["torque_step"] and events[0].inception_ns == 5000 * MS
    assert len(windows) == 1 and not windows[0].usable and "omega" in windows[0].reason


def test_a_window_at_a_trend_log_s_rate_counts_the_grid_s_own_samples() -> None:
    """208.33 reports/s (4.8 ms): a window's bounds fall between reports, and rounding its span
    over the period counted one report more than there are, so every window was refused."""
    from phid_ros.stream.detector import grid_points

    period, anchor = 4_800_000, 1_000_000_123
    rng = np.random.default_rng(0)
    for _ in range(200):
        t0 = anchor + int(rng.integers(-(10**10), 10**10))
        t1 = t0 + int(rng.integers(0, 10**10))
        k = np.arange(-((anchor - t0) // period) - 2, (t1 - anchor) // period + 3)
        stamps = anchor + k * period
        assert grid_points(t0, t1, period, anchor) == int(np.count_nonzero((stamps >= t0) & (stamps <= t1)))
    assert grid_points(0, 10_000_000, 1_000_000, 0) == 11  # on a 1 kHz grid: both ends count, as before
