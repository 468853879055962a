"""Saturation and damper windings mean what the planning models mean: held to ANDES's GENROU.

Our plant with ``magnetic_saturation`` (GENROU form, quadratic) and ``subtransient_dynamics``
(GENROU's dampers) against ANDES's GENROU with the same data, on the same single-machine case:
equal steady states and trajectories equal to about 1e-4 pu (the sensor noise is 3e-3).
About 30 s with ANDES's first-use code generation; skipped without ANDES (a test extra).
"""

from __future__ import annotations

import numpy as np
import pytest

from phid_ros.model.parameters import GeneratorParameters
from phid_ros.sim.effects import REGISTRY
from phid_ros.sim.effects.magnetic_saturation import saturation_curve, saturation_factor
from phid_ros.sim.plant import OperatingPoint, Plant
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import paper_catalogue, with_duration
from phid_ros.sim.sensors import SensorModel

CHANNELS = ("delta", "omega", "i_d", "i_q", "p_e", "q_e")


def phid_config(m: dict) -> SimulationConfig:
    """Our plant with the data of an ANDES GENROU row (machine base)."""
    params = GeneratorParameters(
        H=m["M"] / 2, D=m["D"], X_d=m["xd"], X_q=m["xq"], X_d_prime=m["xd1"], X_q_prime=m["xq1"],
        T_d0_prime=m["Td10"], T_q0_prime=m["Tq10"],
    )  # fmt: skip
    effects = []
    if m["S10"] > 0:
        effects.append(REGISTRY["magnetic_saturation"](s10=m["S10"], s12=m["S12"], form="genrou", curve="quadratic"))
    if m["xd2"] < m["xd1"] or m["xq2"] < m["xq1"]:  # else GENROU's dampers are inert
        dampers = {"x_dpp": m["xd2"], "x_qpp": m["xq2"], "t_d0pp": m["Td20"], "t_q0pp": m["Tq20"], "x_l": m["xl"]}
        effects.append(REGISTRY["subtransient_dynamics"](**dampers))
    return SimulationConfig(params=params, effects=tuple(effects), sensors=SensorModel(noiseless=True))


@pytest.mark.parametrize(
    ("machine", "scenario", "tol"),
    [
        ("genrou-sat-sub", "S10_voltage_0.90", 3e-4),
        ("genrou-sat-sub", "S03_torque_+0.05", 1e-4),
        ("genrou-sat", "S09_voltage_1.10", 3e-4),
        ("genrou-sub", "S13_fault_100ms", 3e-3),  # the fault's currents: 2.4 pu swing, 2 ms RK4 at 1 ms
    ],
)
def test_our_genrou_forms_reproduce_andes_genrou(machine, scenario, tol):
    pytest.importorskip("andes")  # per test: a module-level skip drops the package under pytest 7
    from test.andes_plant import MACHINES, run, system

    m = MACHINES[machine]
    sc = {s.name: with_duration(s, 3.0) for s in paper_catalogue()}[scenario]
    theirs = run(system(m), sc)
    ours = simulate_scenarios([sc], phid_config(m))[0]
    k = min(len(theirs["t"]), ours.n_analysis)
    t = theirs["t"][:k]
    keep = np.ones(k, bool)
    for ts in (sc.t_event, sc.t_clear):
        if ts is not None:  # a step is one sample earlier or later in either: leave 4 ms out
            keep &= np.abs(t - ts) > 0.004
    # the steady state: GENROU's saturated equilibrium (q axis too) and its field voltage
    assert ours.truth["v_f"][0] == pytest.approx(theirs["v_f"][0], abs=1e-5)
    assert ours.truth["delta"][0] == pytest.approx(theirs["delta"][0], abs=1e-6)
    for c in CHANNELS:
        diff = np.max(np.abs(theirs[c][:k][keep] - ours.truth[c][:k][keep]))
        assert diff < tol, (c, diff)


@pytest.mark.parametrize("curve", ["quadratic", "exponential"])
def test_saturation_curves_pass_through_their_two_points(curve):
    c1, c2 = saturation_curve(curve, 0.07, 0.45)
    s = saturation_factor(curve == "exponential", c1, c2, np.array([1.0, 1.2]))
    np.testing.assert_allclose(s, [0.07, 0.45], rtol=1e-12)
    if curve == "quadratic":  # zero below A, as PSS/E's quadratic
        assert float(saturation_factor(curve == "exponential", c1, c2, np.array(0.8 * c1))) == 0.0


def test_gensal_form_saturates_the_field_balance_on_e_q_only():
    # GENSAL (PSS/E; OpenIPSL's efd0): V_f = E'_q (1 + S(E'_q)) + (X_d - X'_d) I_d, and the rotor
    # angle is the unsaturated one (no q-axis term)
    from phid_ros.model.parameters import TABLE1

    sat = REGISTRY["magnetic_saturation"](s10=0.1, s12=0.4, form="gensal")
    plain = Plant(TABLE1).steady_state(OperatingPoint())
    ss = Plant(TABLE1, effects=(sat,)).steady_state(OperatingPoint())
    assert ss.delta == pytest.approx(plain.delta, abs=1e-12)
    s = float(sat.factor(np.array(ss.e_q)))
    expected = ss.e_q * (1 + s) + (TABLE1.X_d - TABLE1.X_d_prime) * ss.i_d
    assert ss.v_f == pytest.approx(expected, rel=1e-12)
    # GENROU's form also loads the q axis: the rotor angle moves
    genrou = Plant(TABLE1, effects=(REGISTRY["magnetic_saturation"](s10=0.1, s12=0.4),)).steady_state(OperatingPoint())
    assert abs(genrou.delta - plain.delta) > 1e-3
