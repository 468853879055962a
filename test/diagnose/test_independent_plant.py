"""The diagnosis on machines it did not simulate: ANDES's GENROU (test/andes_plant.py).

Each study simulates the paper's catalogue (12 s scenarios) with ANDES, adds the simulator's
sensor noise, identifies and diagnoses. The right effect must be named and nothing else, the
held-out unexplained error must fall by at least 90 %, the base parameters the diagnosis
determined must come back within 2 % (D, held at stage 1's value, within twice its std), the
effects' parameters it determined within 10 % (30 % for the damper time constants), and every
parameter further off must be marked not determined. On Table 1's machine (T'_q0 0.135 s)
with dampers, T''_q0 is close enough to T'_q0 that the q axis's two circuits cannot be told
apart, and X'_q and T'_q0 are expected to be so marked; with typical round-rotor q-axis data
(genrou-sub-typical: T'_q0 0.6 s, T''_q0 0.05 s) every base parameter is determined.

Slow, with its reason: ANDES integrates each 12 s scenario in 12 000 steps of about 2 ms of its
own overhead, 7 to 10 minutes for a set on two cores, and the diagnosis 1 to 2 minutes more;
``pytest -m slow test/diagnose/test_independent_plant.py`` runs them (about 60 minutes).
"""

from __future__ import annotations

import pytest

from phid_ros.api import load_recording
from phid_ros.diagnose.options import DiagnoseOptions
from phid_ros.diagnose.results import to_json
from phid_ros.diagnose.workflow import diagnose
from phid_ros.ident.pipeline import IdentifyOptions, identify
from phid_ros.model.parameters import GeneratorParameters
from phid_ros.sim.scenarios import paper_catalogue, with_duration
from phid_ros.stream.scenarios import scenarios_from_recording

pytestmark = pytest.mark.slow

Q_AXIS = {"X_q_prime", "T_q0_prime"}
STUDIES = [  # machine, effects to be named, parameters expected not determined, largest after/before
    ("genrou-4th", [], set(), 1.0),
    ("genrou-sat", ["magnetic_saturation"], set(), 0.10),  # measured -99 %
    ("genrou-sub-typical", ["subtransient_dynamics"], set(), 0.10),  # -94 % (seed 0; 0.4.1: -91 %)
    # Table 1's q axis (T'_q0 0.135 s) with dampers: the q axis's two circuits trade, X'_q, T'_q0 n.d.
    ("genrou-sub-fast", ["subtransient_dynamics"], Q_AXIS, 0.10),  # -93 % (0.4.1, inputs raw: -89 %)
    ("genrou-sub", ["subtransient_dynamics"], Q_AXIS, 0.10),  # -93 %
    ("genrou-sat-sub", ["magnetic_saturation", "subtransient_dynamics"], Q_AXIS, 0.10),  # -98 %
]


def study(machine: str, folder) -> tuple[dict, dict]:
    from test.andes_plant import MACHINES, TRUTH, write_set

    manifest = write_set(folder, MACHINES[machine], [with_duration(s, 12.0) for s in paper_catalogue()], seed=0)
    scenarios, problems = scenarios_from_recording(load_recording(manifest), str(manifest))
    assert not problems
    res = identify(scenarios, IdentifyOptions(baseline=False, validate=False))
    opts = DiagnoseOptions.after(res, workers=0)
    d = diagnose(scenarios, res.parameters, opts)
    return to_json(d, GeneratorParameters(**TRUTH[machine])), res.to_json()


@pytest.mark.parametrize(("machine", "named", "undetermined", "gap_left"), STUDIES, ids=[s[0] for s in STUDIES])
def test_the_right_effect_is_named_on_andes_genrou(machine, named, undetermined, gap_left, tmp_path):
    pytest.importorskip("andes")  # per test: a module-level skip drops the package under pytest 7
    from test.andes_plant import MACHINES

    doc, ident = study(machine, tmp_path)
    assert sorted(e["name"] for e in doc["effects"]) == sorted(named)
    if named:  # the issue asks for a gap 90 % smaller
        assert doc["rmse_after"] <= gap_left * doc["rmse_before"]
    errors = doc["errors_pct"]["after"]
    assert {n for n, ok in doc["identifiable"].items() if not ok} == undetermined, doc["problems"]
    for n, e in errors.items():
        if n != "D" and n not in undetermined:
            assert abs(e) < 2.0, (n, errors)
    assert abs(errors["D"]) / 100 * 0.4 < 2 * ident["uncertainty"]["D"], errors
    m = MACHINES[machine]
    truth = {"s10": ("S10", 0.1), "s12": ("S12", 0.1), "x_dpp": ("xd2", 0.1), "x_qpp": ("xq2", 0.1)}
    truth |= {"t_d0pp": ("Td20", 0.3), "t_q0pp": ("Tq20", 0.3)}
    for e in doc["effects"]:
        p = e["parameters"]
        if e["name"] == "magnetic_saturation":
            assert p["form"] == "genrou" and p["curve"] == "quadratic"
        # as for the base parameters: within its bound where the diagnosis determined it, and
        # every effect parameter further off marked not determined (never published as identified)
        for name, (key, rel) in truth.items():
            if name in p:
                ok = p[name] == pytest.approx(m[key], rel=rel)
                assert ok or not e["identifiable"][name], (e["name"], name, p[name], m[key])
