"""The exciter and the governor from the recordings: named where they act, with their constants;
nothing named where the machine has none (the paper's catalogue from phid's own simulator, whose
field voltage and mechanical power are held but for the scenarios' steps)."""

from __future__ import annotations

import numpy as np
import pytest

from phid_ros.controls.identify import ControlFit, controls_json, identify_controls
from phid_ros.controls.models import SEXS, TGOV1, ControlInputs
from phid_ros.model.channels import Frame

EXCITER = {**SEXS.defaults(), "TA/TB": 0.2, "TB": 5.0, "K": 100.0, "TE": 0.05}
GOVERNOR = {**TGOV1.defaults(), "R": 0.05, "T1": 0.5, "T2": 2.0, "T3": 6.0, "Dt": 0.0}


def switched_in(noisy, clean, seed: int = 0):
    """The catalogue with an SEXS answering the true V_t and a TGOV1 the true speed (its load
    reference stepped where the scenario stepped P_m), the outputs recorded with the simulator's
    sensor noise (0.005 pu on E_fd, 0.002 on P_m); the inputs as the sensors recorded them."""
    rng = np.random.default_rng(seed)
    out = []
    for n, c in zip(noisy, clean, strict=True):
        pre = c.pre_slice()
        dev = {k: np.asarray(c[k]) - float(np.mean(c[k][pre])) for k in ("v_t", "omega", "p_m")}
        step = (np.arange(c.n) >= c.k_event).astype(float)
        x = ControlInputs(c.dt, dev["v_t"], dev["omega"], step)
        p_ref = float(np.mean(dev["p_m"][-1000:])) if c.kind == "torque_step" else 0.0
        cols = n.frame.columns()
        cols["v_f"] = float(np.mean(c["v_f"][pre])) + SEXS.response(EXCITER, x, 0.0) + 0.005 * rng.standard_normal(c.n)
        p_m = TGOV1.response(GOVERNOR, x, p_ref)
        cols["p_m"] = float(np.mean(c["p_m"][pre])) + p_m + 0.002 * rng.standard_normal(c.n)
        out.append(n.with_frame(Frame.of_columns(cols, n.frame.period_ns, n.start_ns)))
    return out


def test_sexs_and_tgov1_switched_into_the_simulator_s_catalogue_are_named_with_their_constants(
    noisy_scenarios, clean_scenarios
):
    found = identify_controls(switched_in(noisy_scenarios, clean_scenarios))
    exciter, governor = found["exciter"], found["governor"]
    assert isinstance(exciter, ControlFit) and isinstance(governor, ControlFit)
    assert exciter.named and exciter.model == "SEXS" and governor.named and governor.model == "TGOV1"
    # the gains within 5 %, the time constants within 10 %, each determined, the limits not
    assert exciter.parameters["K"] == pytest.approx(100.0, rel=0.05)
    assert 1 / governor.parameters["R"] == pytest.approx(20.0, rel=0.05)
    for name, truth in (("TE", 0.05), ("TB", 5.0), ("TA/TB", 0.2)):
        assert exciter.parameters[name] == pytest.approx(truth, rel=0.10), name
    for name, truth in (("T1", 0.5), ("T2", 2.0), ("T3", 6.0)):
        assert governor.parameters[name] == pytest.approx(truth, rel=0.10), name
    assert all(exciter.identifiable[n] for n in ("K", "TE", "TB", "TA/TB"))
    assert exciter.parameters["EMAX"] is None and not exciter.identifiable["EMAX"]
    assert governor.parameters["VMAX"] is None and not governor.identifiable["VMAX"]
    # each torque step's load-reference change is found (the catalogue's +-0.05 .. 0.15 pu)
    steps = {k.split("_torque_")[1]: v for k, v in governor.references.items() if "_torque_" in k}
    for label, size in steps.items():
        assert size == pytest.approx(float(label), abs=0.01), label
    doc = controls_json(found)
    assert doc["exciter"]["model"] == "SEXS" and doc["governor"]["parameters"]["T3"] == governor.parameters["T3"]


def test_a_machine_without_exciter_or_governor_gets_neither(noisy_scenarios):
    """The simulator holds V_f and P_m between the scenarios' steps: a model that explains no
    more than "no control action" is not named, and says so."""
    found = identify_controls(noisy_scenarios)
    for kind in ("exciter", "governor"):
        f = found[kind]
        assert isinstance(f, ControlFit) and not f.named, kind
        assert f"the recordings do not show the {kind}" in f.why
    assert controls_json(found)["exciter"]["model"] is None
