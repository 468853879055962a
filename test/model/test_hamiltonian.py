"""The PH form must reproduce (5)-(8) and satisfy the energy balance."""

import numpy as np
import pytest

from phid_ros.model.equations import reconstruct_fluxes, state_derivatives, stator_currents
from phid_ros.model.hamiltonian import (
    dissipation_matrix,
    hamiltonian,
    hamiltonian_gradient,
    interconnection_matrix,
    ph_dynamics,
    port_inputs,
    power_balance,
)
from phid_ros.model.parameters import TABLE1
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.sensors import SensorModel

OTHER = TABLE1.replace(H=5.1, D=1.3, X_d=1.9, X_q=1.7, X_d_prime=0.31, X_q_prime=0.55, T_d0_prime=6.0, T_q0_prime=0.6)


@pytest.mark.parametrize("params", [TABLE1, OTHER])
@pytest.mark.parametrize("f0", [50.0, 60.0])
def test_j_is_skew_and_r_is_psd(params, f0):
    j = interconnection_matrix(params, f0)
    r = dissipation_matrix(params)
    assert np.array_equal(j, -j.T)
    assert np.allclose(r, r.T)
    assert np.linalg.eigvalsh(r).min() >= 0.0


@pytest.mark.parametrize("params", [TABLE1, OTHER])
@pytest.mark.parametrize("f0", [50.0, 60.0])
def test_ph_form_equals_equations_5_to_8_at_random_states(params, f0):
    rng = np.random.default_rng(7)
    n = 200
    x = np.stack(
        [rng.uniform(-3, 3, n), rng.uniform(0.95, 1.05, n), rng.uniform(0.5, 1.5, n), rng.uniform(-0.8, 0.8, n)]
    )
    p_m, p_e, v_f, i_d, i_q = (rng.uniform(-2, 2, n) for _ in range(5))
    explicit = state_derivatives(x, p_m, p_e, v_f, i_d, i_q, params, f0)
    ph = ph_dynamics(x, port_inputs(p_m, p_e, v_f, i_d, i_q), params, f0)
    assert np.allclose(ph, explicit, rtol=1e-12, atol=1e-12)


def test_gradient_matches_finite_differences():
    x = np.array([0.7, 1.01, 1.1, 0.4])
    grad = hamiltonian_gradient(x, TABLE1)
    h = 1e-6
    for i in range(4):
        e = np.zeros(4)
        e[i] = h
        hp = hamiltonian(*(x + e)[1:], TABLE1).total
        hm = hamiltonian(*(x - e)[1:], TABLE1).total
        assert np.isclose((hp - hm) / (2 * h), grad[i], atol=1e-7)


def test_energy_balance_along_a_simulated_fault():
    """∫(supply - dissipation) dt equals the change of ℋ, and dℋ/dt <= supply everywhere."""
    from dataclasses import replace

    from phid_ros.sim.scenarios import find_scenario

    cfg = SimulationConfig(sensors=SensorModel(noiseless=True), restore_ramp=0.0, restore_hold=0.0)
    run = simulate_scenarios([replace(find_scenario("S14"), duration=5.0)], cfg)[0]
    s, tr = run.states, run.truth
    x = np.stack([s["delta"], s["omega"], s["e_q"], s["e_d"]])
    u = port_inputs(tr["p_m"], tr["p_e"], tr["v_f"], tr["i_d"], tr["i_q"])
    bal = power_balance(x, u, TABLE1)
    h = hamiltonian(s["omega"], s["e_q"], s["e_d"], TABLE1).total
    dt = run.t[1] - run.t[0]
    # per step, ℋ(k+1) - ℋ(k) must equal the trapezoid of dℋ/dt; the network (and so u)
    # jumps at fault inception and clearing, where a trapezoid cannot span the jump
    sc = run.scenario
    faulted = (run.t >= sc.t_event - dt / 2) & (run.t < sc.t_clear - dt / 2)
    smooth = faulted[1:] == faulted[:-1]
    step_change = np.diff(h)
    trapezoid = 0.5 * (bal.dh_dt[1:] + bal.dh_dt[:-1]) * dt
    assert smooth.sum() == len(smooth) - 2
    assert np.max(np.abs(step_change - trapezoid)[smooth]) < 1e-7
    assert np.max(np.abs(step_change[smooth])) > 1e-4  # the check is not vacuous
    assert np.all(bal.dissipation >= 0.0)
    assert np.all(bal.supply - bal.dh_dt >= -1e-15)


def test_reconstruction_inverts_the_stator_equations():
    rng = np.random.default_rng(3)
    e_q, e_d, v_d, v_q = rng.uniform(0.2, 1.2, (4, 30))
    i_d, i_q = stator_currents(e_q, e_d, v_d, v_q, TABLE1)
    rq, rd = reconstruct_fluxes(v_d, v_q, i_d, i_q, TABLE1.X_d_prime, TABLE1.X_q_prime)
    assert np.allclose(rq, e_q) and np.allclose(rd, e_d)
