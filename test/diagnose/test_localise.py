"""Gap localisation: where a hidden effect shows up when the model lacks it."""

from dataclasses import replace

import pytest

from phid_ros.diagnose.localise import localise
from phid_ros.model.parameters import TABLE1
from phid_ros.sim.effects import parse_effect
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import paper_catalogue
from test.conftest import scenario_from_run


def report(effect: str | None):
    cat = [replace(s, duration=10.0) for s in paper_catalogue() if s.name[:3] in ("S04", "S10", "S14")]
    effects = (parse_effect(effect),) if effect else ()
    runs = simulate_scenarios(cat, SimulationConfig(restore_ramp=1.0, restore_hold=1.0, effects=effects))
    return localise([scenario_from_run(r) for r in runs], TABLE1)


@pytest.fixture(scope="module")
def baseline():
    return report(None)


@pytest.mark.parametrize(
    "effect, channel, band, phases",
    [
        ("shaft_torsion", {"omega"}, "fast (3-20 Hz)", {"settling", "first_second"}),
        ("sensor_delay=stream=pmu,delay_ms=20", {"omega"}, "electromechanical (0.5-3 Hz)", {"first_second"}),
        # GENSAL's form loads the field winding alone: the rotor angle drifts. GENROU's also loads
        # the q-axis winding, and Q_e and the angle carry the gap about equally (17 500 and 17 200)
        ("magnetic_saturation=s10=0.1,s12=0.4,form=gensal", {"delta"}, "slow (< 0.5 Hz)", {"settling", "steady_state"}),
        ("magnetic_saturation=s10=0.1,s12=0.4", {"q_e", "delta"}, "slow (< 0.5 Hz)", {"settling", "steady_state"}),
        ("stator_resistance=r_a=0.01", {"delta"}, "slow (< 0.5 Hz)", {"settling"}),
    ],
)
def test_a_missing_effect_stands_out_where_its_physics_acts(baseline, effect, channel, band, phases):
    rep = report(effect)
    assert rep.total > 20 * baseline.total  # the model without the effect leaves a large gap
    assert rep.top("by_channel", 1)[0][0] in channel
    assert rep.top("by_band", 1)[0][0] == band
    assert rep.top("by_phase", 1)[0][0] in phases


def test_a_complete_model_leaves_little(baseline):
    # no effect hidden: the residual is close to the sensor noise (what is left is the play-in's discretisation)
    assert baseline.total < 20
    assert set(baseline.by_kind) == {"torque_step", "voltage_step", "fault"}
