"""The diagnosis on a salient-pole machine it did not simulate: STEPS's GENSAL (test/steps_plant.py).

Each study simulates the paper's catalogue (12 s scenarios) with STEPS on phid's single-machine
case (1000 MVA machine on a 100 MVA system base), adds the simulator's sensor noise, identifies
and diagnoses. The right effects must be named and nothing else (no delay: the play-in's own
discretisation is not one), the held-out unexplained error must fall by at least 90 %, and the
base parameters a GENSAL has (H, X_d, X_q, X'_d, T'_d0) must come back within 2 % where the
diagnosis determined them, and every one further off must be marked not determined. D is
phid's power form, PSS/E's D plus P_m (STEPS computes PSS/E's (P_m - D dw)/(1 + dw)): within
twice its std of the span of P_m the events held. A GENSAL has no q-axis field winding: the
fourth-order model's X'_q, T'_q0 take the damper (X'', T''_q0) until the damper is named; then
X'_q goes to X_q and T'_q0 acts on nothing (not determined).

STEPS's GENSAL saturates GENROU's way (on |psi''|, both axes; see test/steps_plant.py), so the
saturation named on ``gensal-sat`` must be in GENROU's form. Slow, with its reason: STEPS is
built from source (benchmarks/steps_build.sh, not installable from the package index here),
and each study takes about a minute (30 s of STEPS, 30 s of diagnosis on two cores);
``pytest -m slow test/diagnose/test_steps_gensal.py`` runs them.
"""

from __future__ import annotations

import pytest

from phid_ros.api import load_recording
from phid_ros.diagnose.options import DiagnoseOptions
from phid_ros.diagnose.results import to_json
from phid_ros.diagnose.workflow import diagnose
from phid_ros.ident.pipeline import IdentifyOptions, identify
from phid_ros.sim.scenarios import paper_catalogue, with_duration
from phid_ros.stream.scenarios import scenarios_from_recording

pytestmark = pytest.mark.slow

Q_AXIS = {"X_q_prime", "T_q0_prime"}
STUDIES = [  # machine, effects named, form of the saturation, base parameters expected within 2 %
    ("gensal", ["subtransient_dynamics"], None, 6),  # measured: -93 %, six of six within 2 % (D +1.8 %)
    # with the fit's V_t, theta_t played in raw (0.4.1) T'_d0 +3.1 %, not determined, X_d +1.6 %;
    # smoothed: T'_d0 +1.25 %, X_d +0.64 %, both determined
    ("gensal-sat", ["magnetic_saturation", "subtransient_dynamics"], "genrou", 6),  # measured -96 %
    ("gensal-controls", ["subtransient_dynamics"], None, 6),  # SEXS and TGOV1 in the loop: -94 %
    ("gensal-sat-controls", ["magnetic_saturation", "subtransient_dynamics"], "genrou", 6),  # -95 %
]


def study(machine: str, folder) -> tuple[dict, dict]:
    from test.steps_plant import MACHINES, write_set

    manifest = write_set(folder, MACHINES[machine], [with_duration(s, 12.0) for s in paper_catalogue()], seed=0)
    scenarios, problems = scenarios_from_recording(load_recording(manifest), str(manifest))
    assert not problems
    res = identify(scenarios, IdentifyOptions(baseline=False, validate=False))
    d = diagnose(scenarios, res.parameters, DiagnoseOptions.after(res, workers=0))
    return to_json(d), res.to_json()


@pytest.mark.parametrize(("machine", "named", "form", "within"), STUDIES, ids=[s[0] for s in STUDIES])
def test_the_right_effects_are_named_on_steps_gensal(machine, named, form, within, tmp_path):
    pytest.importorskip("stepspy")  # per test: a module-level skip drops the package under pytest 7
    from test.steps_plant import TRUTH

    doc, ident = study(machine, tmp_path)
    assert sorted(e["name"] for e in doc["effects"]) == sorted(named), doc["effects"]
    assert doc["rmse_after"] <= 0.10 * doc["rmse_before"]
    sat = [e for e in doc["effects"] if e["name"] == "magnetic_saturation"]
    if form is not None:
        assert sat[0]["parameters"]["form"] == form
    after = doc["parameters"]
    undetermined = {n for n, ok in doc["identifiable"].items() if not ok}
    truth = dict(TRUTH[machine])
    # with the damper named the q axis has no transient circuit left: X'_q goes to X_q (where the
    # data determine it) and T'_q0 acts on nothing
    assert "T_q0_prime" in undetermined
    if "X_q_prime" not in undetermined:
        assert abs(after["X_q_prime"] / truth["X_q"] - 1.0) < 0.02, after["X_q_prime"]
    close = []
    for n in ("H", "X_d", "X_q", "X_d_prime", "T_d0_prime"):
        error = after[n] / truth[n] - 1.0
        if n not in undetermined:
            assert abs(error) < 0.02, (n, after[n], truth[n])
        close.append(abs(error) < 0.02)
    # D, held at stage 1's value, is phid's power form: PSS/E's D plus P_m, linearised where each
    # event held the machine (0.8 before it, up to 0.95 after a torque step), so within 2 std of
    # that span; the .dyr's D - P_m0 then lies within it less P_m0
    std, p_m0 = ident["uncertainty"]["D"], ident["operating_point"]["p_m_pu"]
    low, high = truth["D"] - 2 * std, truth["D"] + 0.15 + 2 * std
    assert low < after["D"] < high, (after["D"], low, high)
    assert abs(p_m0 - 0.8) < 0.01
    close.append(True)
    assert sum(close) >= within, (after, undetermined)


def test_two_loadings_of_the_saturated_machine_give_its_constants_not_a_biased_x_d(tmp_path):
    """The catalogue's identification scenarios repeated at a second loading (P 0.5, V_t 1.05,
    Q 0.45) cover more of the saturation curve. With V_t and theta_t played in raw, the fit gave
    X_d +3.8 % with a 0.2 % std, marked determined: a wrong number published as identified.
    Measured with the fit's inputs smoothed (seed 0): H -0.19 %, X_d +0.47 %, X_q -0.22 %,
    X'_d +0.11 %, T'_d0 +1.45 %, each determined; held-out 14.4 -> 0.77 sigma."""
    pytest.importorskip("stepspy")
    from dataclasses import replace

    from phid_ros.sim.plant import OperatingPoint
    from phid_ros.sim.runner import SimulationConfig
    from test.plants import noisy_set
    from test.steps_plant import MACHINE_MVA, MACHINES, TRUTH, Case

    second = SimulationConfig(operating_point=OperatingPoint(p_e=0.5, v_t=1.05, q_e=0.45))
    base = [with_duration(s, 12.0) for s in paper_catalogue()]
    extra = [replace(s, name=s.name + "_b") for s in base if s.role == "identify"]
    at = {s.name: second for s in extra}
    machine = MACHINES["gensal-sat"]
    manifest = noisy_set(
        tmp_path,
        base + extra,
        lambda sc: Case(machine, at.get(sc.name, SimulationConfig())).run(sc),
        mva=MACHINE_MVA,
        source="steps",
        description="STEPS GENSAL with saturation at two loadings",
        seed=0,
    )
    scenarios, problems = scenarios_from_recording(load_recording(manifest), str(manifest))
    assert not problems
    res = identify(scenarios, IdentifyOptions(baseline=False, validate=False))
    doc = to_json(diagnose(scenarios, res.parameters, DiagnoseOptions.after(res, workers=0)))
    assert sorted(e["name"] for e in doc["effects"]) == ["magnetic_saturation", "subtransient_dynamics"]
    assert doc["rmse_after"] <= 0.10 * doc["rmse_before"]
    truth = TRUTH["gensal-sat"]
    for n in ("H", "X_d", "X_q", "X_d_prime", "T_d0_prime"):
        error = doc["parameters"][n] / truth[n] - 1.0
        # determined and within 2 %: a parameter further off must at least be marked
        assert doc["identifiable"][n] and abs(error) < 0.02, (n, doc["parameters"][n], truth[n])


@pytest.mark.parametrize("machine", ["gensal-controls", "gensal-sat-controls"])
def test_steps_s_sexs_and_tgov1_are_identified_from_the_recordings(machine, tmp_path):
    """STEPS's SEXS (TA/TB 0.2, TB 5 s, K 100, TE 0.05 s, E_MAX 5, which the faults reach) and
    TGOV1 (R 0.05, T1 0.5 s, T2 2 s, T3 6 s) in the loop: named, the gains within 5 %, the time
    constants within 10 %, the ceiling found and within 10 %. Measured on gensal-controls: K
    +0.9 %, E_MAX +1.9 %, 1/R +0.6 %, TE -1 %, TB +1 %, T1 +0.0 %, T2 -0.5 %, T3 -0.1 %. (Judged on
    its fit with the faults, SEXS lost to IEEET1, which has no ceiling to fit.)"""
    pytest.importorskip("stepspy")
    from phid_ros.controls.fit import ControlFit
    from phid_ros.controls.identify import identify_controls
    from test.steps_plant import MACHINES, write_set

    manifest = write_set(tmp_path, MACHINES[machine], [with_duration(s, 12.0) for s in paper_catalogue()], seed=0)
    scenarios, _ = scenarios_from_recording(load_recording(manifest), str(manifest))
    found = identify_controls(scenarios)
    exciter, governor = found["exciter"], found["governor"]
    assert isinstance(exciter, ControlFit) and isinstance(governor, ControlFit)
    assert (exciter.model, exciter.named, governor.model, governor.named) == ("SEXS", True, "TGOV1", True)
    assert exciter.parameters["K"] == pytest.approx(100.0, rel=0.05)
    assert exciter.parameters["EMAX"] == pytest.approx(5.0, rel=0.10) and set(exciter.limits) == {"EMAX"}
    assert 1 / governor.parameters["R"] == pytest.approx(20.0, rel=0.05)
    for fit, truth in ((exciter, {"TA/TB": 0.2, "TB": 5.0, "TE": 0.05}), (governor, {"T1": 0.5, "T2": 2.0, "T3": 6.0})):
        for name, value in truth.items():
            assert fit.parameters[name] == pytest.approx(value, rel=0.10), (name, fit.parameters[name])


def test_steps_s_ieeet1_and_ieeeg1_are_identified_from_the_recordings(tmp_path):
    """STEPS's own IEEET1 (K_A 50, T_A 0.05 s, K_E 1, T_E 0.5 s, K_F 0.05, T_F 1 s) and IEEEG1
    (K 20, servo 0.1 s, steam chest 0.3 s, K_1 0.3, reheater 7 s) in the loop: implementations
    phid did not write. With the unit's models named (``--exciter IEEET1 --governor IEEEG1``)
    the gains within 5 % and every time constant the fit determines within 10 %; left to choose,
    each is named or listed as fitting as well as the one named (IEEET1's rate feedback answers
    like EXST1's lead-lag, IEEEG1's reheat like TGOV1's). STEPS has no HYGOV: phid's HYGOV is
    checked against ANDES's (test/controls/test_unit_validation.py). Measured (seed 0): all ten
    determined, K_A +0.4 %, T_A -0.6 %, T_E +0.4 %, K_F +0.2 %, T_F +0.1 %; K +0.7 %, T_3 +0.8 %,
    T_4 -1.1 %, K_1 -0.5 %, T_5 -0.4 %; unrestricted, IEEET1 named with EXST1 and ESST5B listed
    as fitting as well, IEEEG1 named alone."""
    pytest.importorskip("stepspy")
    from phid_ros.controls.fit import ControlFit
    from phid_ros.controls.identify import identify_controls
    from test.steps_plant import MACHINES, write_set

    manifest = write_set(
        tmp_path, MACHINES["gensal-ieeet1-ieeeg1"], [with_duration(s, 12.0) for s in paper_catalogue()], seed=0
    )
    scenarios, _ = scenarios_from_recording(load_recording(manifest), str(manifest))
    named = identify_controls(scenarios, {"exciter": ["IEEET1"], "governor": ["IEEEG1"]})
    exciter, governor = named["exciter"], named["governor"]
    assert isinstance(exciter, ControlFit) and isinstance(governor, ControlFit)
    assert (exciter.named, governor.named) == (True, True), (exciter.why, governor.why)
    gains = {"KA": 50.0, "K": 20.0, "K1": 0.3}
    lags = {"TA": 0.05, "TE": 0.5, "KF": 0.05, "TF": 1.0, "T3": 0.1, "T4": 0.3, "T5": 7.0}
    determined = 0
    for fit in (exciter, governor):
        for name, value in fit.parameters.items():
            truth = gains.get(name, lags.get(name))
            if truth is None or not fit.identifiable.get(name):
                continue
            determined += 1
            rel = 0.05 if name in gains else 0.10
            assert value == pytest.approx(truth, rel=rel), (fit.model, name, value, truth)
    assert exciter.identifiable["KA"] and governor.identifiable["K"]
    assert determined >= 8, (exciter.identifiable, governor.identifiable)  # measured: all ten

    chosen = identify_controls(scenarios)
    for kind, truth in (("exciter", "IEEET1"), ("governor", "IEEEG1")):
        fit = chosen[kind]
        assert isinstance(fit, ControlFit) and fit.named, fit
        assert truth == fit.model or truth in fit.alternatives, (kind, fit.model, fit.alternatives)
