"""The missing-physics workflow on data with hidden effects: it names what is there, and only that.

Each effect is hidden at a random magnitude drawn from its realistic range (the ranges declared
with the effect; fixed seeds), the workflow is not told which. A sensor latency is drawn on the
PT/CT, encoder or PMU stream: the field voltage is constant in every scenario (no AVR), so a
latency on the excitation stream changes nothing that can be measured.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from phid_ros.diagnose.options import DiagnoseOptions
from phid_ros.diagnose.results import to_json
from phid_ros.diagnose.workflow import diagnose
from phid_ros.ident.pipeline import IdentifyOptions, identify
from phid_ros.model.parameters import TABLE1
from phid_ros.sim.effects import REGISTRY, PlantEffect
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import paper_catalogue
from test.conftest import scenario_from_run

OBSERVABLE_STREAMS = ("pt_ct", "encoder", "pmu")

# Each diagnosis fits every candidate with all eight base parameters free: 0.6-2.5 minutes on
# two cores per data set, about ten minutes for the seven. Run with `pytest -m slow`.
pytestmark = pytest.mark.slow


def hidden(name: str, seed: int) -> PlantEffect:
    """The effect at a random magnitude inside its declared realistic range."""
    rng = np.random.default_rng(seed)
    cls = REGISTRY[name]
    values: dict = {}
    for p in cls.parameters:
        if name == "subtransient_dynamics" and p.name == "x_l":
            continue  # the diagnosis holds X_l at its planning default; so does the hidden plant
        if name == "magnetic_saturation" and p.name == "curve":
            # around one operating point the quadratic and the exponential curve fit alike, and the
            # diagnosis names the planning models' quadratic unless the data clearly say otherwise
            values[p.name] = "quadratic"
        elif p.choices:
            values[p.name] = str(rng.choice(OBSERVABLE_STREAMS if p.name == "stream" else p.choices))
        else:
            values[p.name] = float(rng.uniform(p.low, p.high))
    if name == "magnetic_saturation":  # S(1.2) above S(1.0), as every open-circuit curve has it
        s12 = next(p for p in cls.parameters if p.name == "s12")
        values["s12"] = float(rng.uniform(max(s12.low, 1.5 * values["s10"]), 0.8))
    return cls(**values)


def run(effects: tuple[PlantEffect, ...], seed: int = 0) -> dict:
    cat = [replace(s, duration=12.0) if s.role == "identify" else s for s in paper_catalogue()]
    cfg = SimulationConfig(restore_ramp=1.0, restore_hold=1.0, effects=effects)
    scs = [scenario_from_run(r) for r in simulate_scenarios(cat, cfg, seed_offset=100 * seed)]
    res = identify(scs, IdentifyOptions(baseline=False, validate=False))
    opts = DiagnoseOptions.after(res, workers=0)  # as phid diagnose
    doc = to_json(diagnose(scs, res.parameters, opts), TABLE1, [e.as_dict() for e in effects])
    m = doc["mean_abs_error_pct_without_D"]
    print(  # the README's table is read from these lines (pytest -s)
        f"\nSTUDY hidden={doc['truth_effects']} named={[(e['name'], e['parameters']) for e in doc['effects']]} "
        f"heldout={doc['rmse_before']:.2f}->{doc['rmse_after']:.2f} base={m['identified']:.2f}/{m['base_refit']:.2f}/"
        f"{m['after']:.2f} undetermined={[n for n, ok in doc['identifiable'].items() if not ok]}"
    )
    return doc


@pytest.mark.parametrize(
    "name, seed",
    [
        ("stator_resistance", 1),
        ("magnetic_saturation", 2),
        ("sensor_delay", 3),
        ("subtransient_dynamics", 4),
        ("shaft_torsion", 5),
    ],
)
def test_a_hidden_effect_is_named_and_halves_the_heldout_error(name, seed):
    effect = hidden(name, seed)
    doc = run((effect,), seed)
    assert [e["name"] for e in doc["effects"]] == [name], doc["truth_effects"]
    assert doc["rmse_after"] <= 0.5 * doc["rmse_before"]
    # the base parameters after adding the effect are closer to the truth than the identified ones.
    # D is left out of the mean: it is 3 % of this plant's damping and output error places it
    # within about +-15 % whatever the model (the JSON reports it, and with it, too)
    m = doc["mean_abs_error_pct_without_D"]
    assert m["after"] < m["base_refit"]
    # an effect that barely moves the three-stage estimates (a shaft mode at tens of Hz, seen: 0.16 %)
    # leaves their estimates within a fraction of a per cent; there the refit need only stay as close
    assert m["after"] < max(m["identified"], 0.5)
    # and the effect's own parameters are found
    found = doc["effects"][0]["parameters"]
    for p in REGISTRY[name].parameters:
        if p.choices:
            assert found[p.name] == effect[p.name]
        elif p.name not in ("d_shaft", "x_l"):  # shaft damping is weakly identifiable (the ring-down is
            # short); X_l is held at its default in both plant and diagnosis
            # damper time constants of tens of ms are seen through 2 ms play-in steps: +-50 %
            rel = 0.5 if p.name.startswith("t_") else 0.25
            assert found[p.name] == pytest.approx(effect[p.name], rel=rel, abs=2.0 if p.unit == "ms" else 0.0), p.name


def test_nothing_hidden_names_nothing():
    doc = run(())
    assert doc["effects"] == []
    assert doc["rmse_after"] == doc["rmse_before"] < 0.5  # held-out error is at the sensor-noise floor


def test_two_hidden_effects_are_both_named():
    effects = (hidden("stator_resistance", 11), hidden("shaft_torsion", 12))
    doc = run(effects, 6)
    assert sorted(e["name"] for e in doc["effects"]) == ["shaft_torsion", "stator_resistance"]
    assert doc["rmse_after"] <= 0.5 * doc["rmse_before"]
    m = doc["mean_abs_error_pct_without_D"]
    assert m["after"] < m["base_refit"]
    assert m["after"] < max(m["identified"], 0.5)
