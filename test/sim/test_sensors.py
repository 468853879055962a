import numpy as np

from phid_ros.sim.sensors import DEFAULT_CHANNEL_SENSORS, SensorModel


def _truth(n=20000):
    t = np.linspace(0, 1, n)
    return {name: 0.8 + 0.1 * np.sin(7 * t) for name in DEFAULT_CHANNEL_SENSORS}


def test_noise_level_and_quantisation_per_channel():
    truth = _truth()
    meas = SensorModel(seed=3).measure(truth)
    for name, spec in DEFAULT_CHANNEL_SENSORS.items():
        err = meas[name] - truth[name]
        assert abs(np.std(err) - spec.noise_std) < 0.05 * spec.noise_std + spec.lsb
        assert np.allclose(meas[name] / spec.lsb, np.round(meas[name] / spec.lsb), atol=1e-9)


def test_seeded_and_independent_per_stream():
    truth = _truth(1000)
    a = SensorModel(seed=1).measure(truth, stream_seed=0)
    b = SensorModel(seed=1).measure(truth, stream_seed=0)
    c = SensorModel(seed=2).measure(truth, stream_seed=0)
    d = SensorModel(seed=1).measure(truth, stream_seed=1)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(a["v_t"], c["v_t"])
    assert not np.array_equal(a["v_t"], d["v_t"])


def test_noiseless_is_exact():
    truth = _truth(100)
    meas = SensorModel(noiseless=True).measure(truth)
    assert all(np.array_equal(meas[k], truth[k]) for k in truth)
