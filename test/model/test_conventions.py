import numpy as np

from phid_ros.model.conventions import dq_to_network, dq_to_terminal, network_to_dq, omega_s, terminal_to_dq


def test_internal_angle_is_delta_minus_theta_t():
    v_d, v_q = terminal_to_dq(1.0, 0.9, 0.2)
    assert np.isclose(v_d, np.sin(0.7)) and np.isclose(v_q, np.cos(0.7))


def test_round_trips():
    rng = np.random.default_rng(1)
    v, delta, theta = rng.uniform(0.1, 1.5, 50), rng.uniform(-3, 3, 50), rng.uniform(-3, 3, 50)
    vt, th = dq_to_terminal(*terminal_to_dq(v, delta, theta), delta)
    assert np.allclose(vt, v)
    assert np.allclose(np.angle(np.exp(1j * (th - theta))), 0.0)
    z = v * np.exp(1j * theta)
    assert np.allclose(dq_to_network(network_to_dq(z, delta), delta), z)
    # the two maps agree: the d/q of a network phasor are (9)-(10) with the internal angle
    dq = network_to_dq(z, delta)
    vd, vq = terminal_to_dq(v, delta, theta)
    assert np.allclose(dq.real, vd) and np.allclose(dq.imag, vq)


def test_nominal_frequency_is_a_parameter():
    assert np.isclose(omega_s(50.0), 100 * np.pi)
    assert np.isclose(omega_s(60.0), 120 * np.pi)
