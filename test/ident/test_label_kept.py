"""A label the signals dispute is kept and said as a fact of the scenario, not found back in its notes."""

from __future__ import annotations

from phid_ros.ident.pipeline import identify
from phid_ros.ident.scenario import make_scenario, scenario_from_simulation
from phid_ros.sim.runner import simulate_scenarios
from phid_ros.sim.scenarios import Scenario


def test_a_fault_labelled_a_torque_step_keeps_its_label_and_says_so_once() -> None:
    runs = simulate_scenarios(
        [Scenario("F", "fault", 0.1, duration=6.0), Scenario("T", "torque_step", 0.1, duration=6.0)]
    )
    fault, torque = (scenario_from_simulation(r, r.measured) for r in runs)
    relabelled = make_scenario("F", fault.frame, kind="torque_step")
    assert relabelled.kind == "torque_step"
    assert relabelled.label_kept.startswith("labelled torque_step but the signals say fault")
    assert relabelled.label_kept in relabelled.notes
    assert make_scenario("T", torque.frame, kind="torque_step").label_kept == ""
    res = identify([relabelled, torque])
    assert res.label_disputes == [f"F: {relabelled.label_kept}"]
    assert res.problems.count(res.label_disputes[0]) == 1
    assert res.light().label_disputes == res.label_disputes
