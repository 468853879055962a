from dataclasses import replace

import numpy as np
import pytest

from phid_ros.errors import SimulationError
from phid_ros.model.parameters import TABLE1
from phid_ros.sim.network import Network
from phid_ros.sim.plant import OperatingPoint, Plant
from phid_ros.sim.runner import SimulationConfig, build_inputs, simulate_scenarios
from phid_ros.sim.scenarios import Scenario, find_scenario
from phid_ros.sim.sensors import SensorModel

NOISELESS = SimulationConfig(sensors=SensorModel(noiseless=True), restore_ramp=1.0, restore_hold=1.0)


@pytest.mark.parametrize("op", [OperatingPoint(), OperatingPoint(0.5, 1.05, 0.1), OperatingPoint(0.9, 0.98, 0.45)])
@pytest.mark.parametrize("f0", [50.0, 60.0])
def test_initialisation_is_an_equilibrium(op, f0):
    plant = Plant(TABLE1, f_nominal_hz=f0)
    ss = plant.steady_state(op)
    sc = Scenario("quiet", "torque_step", 0.0, duration=2.0)
    inputs = build_inputs([sc], plant, ss, NOISELESS)
    dx = plant.derivatives(ss.x[:, None], inputs)
    assert np.max(np.abs(dx)) < 1e-9
    # and it delivers the requested operating point at the terminals
    traj = plant.simulate(
        ss.x[:, None],
        replace(
            inputs,
            p_m=inputs.p_m[:10],
            v_f=inputs.v_f[:10],
            v_th_abs=inputs.v_th_abs[:10],
            v_th_angle=inputs.v_th_angle[:10],
            r_th=inputs.r_th[:10],
            x_th=inputs.x_th[:10],
        ),
        1e-3,
    )
    assert np.allclose(traj.p_e, op.p_e, atol=1e-12)
    assert np.allclose(traj.q_e, op.q_e, atol=1e-12)
    assert np.allclose(traj.v_t, op.v_t, atol=1e-12)
    assert np.allclose(traj.theta_t, ss.theta_t, atol=1e-12)


def test_fault_drops_terminal_voltage_below_0_3_of_prefault_and_recovers():
    sc = replace(find_scenario("S15"), duration=6.0)
    run = simulate_scenarios([sc], NOISELESS)[0]
    v = run.truth["v_t"]
    t = run.t
    v_pf = v[t < sc.t_event].mean()
    during = (t >= sc.t_event) & (t < sc.t_clear)
    assert np.all(v[during] < 0.3 * v_pf)
    assert np.all(v[(t < sc.t_event)] > 0.99 * v_pf)
    # inception exactly at the event sample, clearing exactly at t_event + duration
    below = np.flatnonzero(v < 0.3 * v_pf)
    assert np.isclose(t[below[0]], sc.t_event) and np.isclose(t[below[-1]], sc.t_clear - 1e-3)
    assert abs(v[int(5.9 / 1e-3)] - v_pf) < 0.01  # back near the operating point


def test_torque_step_reaches_the_new_equilibrium_with_power_balance():
    sc = replace(find_scenario("S04"), duration=30.0)
    run = simulate_scenarios([sc], NOISELESS)[0]
    n = run.n_analysis
    tail = slice(int(0.8 * n), n)
    assert np.allclose(run.truth["p_e"][tail], 0.9, atol=2e-4)  # P_e follows P_m
    assert np.allclose(run.truth["omega"][tail], 1.0, atol=1e-5)


def _decay_rate(omega: np.ndarray, t: np.ndarray) -> float:
    from scipy.signal import find_peaks

    w = omega - omega[-2000:].mean()
    peaks, _ = find_peaks(w)
    peaks = peaks[:6]
    return float(-np.polyfit(t[peaks], np.log(np.abs(w[peaks])), 1)[0])


def test_generator_damping_adds_d_over_4h_to_the_decay_rate():
    """Switching D off (the paper's dampingless runs) slows the swing decay by D/(4H)."""
    normal = replace(find_scenario("S04"), duration=12.0)
    dampingless = replace(find_scenario("S01"), duration=12.0)
    runs = simulate_scenarios([normal, dampingless], NOISELESS)
    after = slice(1000, 12000)
    rates = [_decay_rate(r.truth["omega"][after], r.t[after]) for r in runs]
    expected = TABLE1.D / (4 * TABLE1.H)
    assert rates[0] > rates[1] > 0
    assert abs((rates[0] - rates[1]) - expected) < 0.3 * expected


def test_vectorised_batch_equals_single_runs():
    scs = [replace(find_scenario(n), duration=3.0) for n in ("S04", "S10", "S13")]
    batch = simulate_scenarios(scs, NOISELESS)
    for sc, b in zip(scs, batch):
        single = simulate_scenarios([sc], NOISELESS)[0]
        for k in single.truth:
            assert np.allclose(single.truth[k], b.truth[k], rtol=0, atol=1e-12)


def test_bad_settings_are_refused():
    plant = Plant(TABLE1)
    ss = plant.steady_state(OperatingPoint())
    inputs = build_inputs([Scenario("q", "torque_step", 0.0, duration=2.0)], plant, ss, NOISELESS)
    with pytest.raises(SimulationError, match="time step"):
        plant.simulate(ss.x[:, None], inputs, 2e-3)
    with pytest.raises(SimulationError, match="loses synchronism"):
        simulate_scenarios([Scenario("huge", "torque_step", 0.8, duration=5.0)], NOISELESS)
    with pytest.raises(SimulationError, match="kind"):
        Scenario("x", "earthquake", 1.0)
    with pytest.raises(SimulationError, match="non-negative"):
        Network(x_transformer=-0.1)


@pytest.mark.parametrize("f0", [50.0, 60.0])
def test_the_plant_integrates_the_model_equations(f0):
    """Without effects, the simulator's state equations are model/equations.py's (5)-(8), with its
    stator currents (solved with the network) satisfying (11)-(12) at the terminals."""
    from phid_ros.model.equations import Coefficients, currents, derivatives
    from phid_ros.sim.plant import Inputs

    rng = np.random.default_rng(5)
    n = 40
    plant = Plant(TABLE1, f_nominal_hz=f0)
    x = np.array(
        [rng.uniform(-1, 1.5, n), rng.uniform(0.97, 1.03, n), rng.uniform(0.6, 1.3, n), rng.uniform(-0.6, 0.2, n)]
    )
    row = lambda lo, hi: rng.uniform(lo, hi, (1, n))  # noqa: E731
    damping = rng.uniform(0.0, 2.0, n)
    inputs = Inputs(row(0.2, 1.0), row(1.0, 3.0), row(0.8, 1.1), row(-0.3, 0.3), row(0.0, 0.02), row(0.2, 0.6), damping)
    i_d, i_q, _, _ = plant._currents(
        x[0], x[2], x[3], inputs.v_th_abs[0], inputs.v_th_angle[0], inputs.r_th[0], inputs.x_th[0]
    )
    # the terminal voltage the stator sees, from (11)-(12)
    v_d, v_q = x[3] + TABLE1.X_q_prime * i_q, x[2] - TABLE1.X_d_prime * i_d
    c = Coefficients.of(TABLE1, f0, damping=damping / TABLE1.D)
    assert np.allclose(currents(x[2], x[3], v_d, v_q, c), (i_d, i_q), rtol=1e-12, atol=1e-12)
    expect = derivatives(x, inputs.p_m[0], v_d * i_d + v_q * i_q, inputs.v_f[0], i_d, i_q, c)
    assert np.allclose(plant.derivatives(x, inputs), expect, rtol=1e-12, atol=1e-12)
