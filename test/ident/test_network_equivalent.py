"""The network's Thevenin reactance seen from the terminals, from the recording alone: the
project's own simulator (a machine behind its step-up transformer and line, X_e 0.20 pu on the
machine's base, sensor noise) through a field step, a torque step and a no-load step; a scenario
whose Q stands still says nothing."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from phid_ros.ident.network_equivalent import thevenin_reactance
from phid_ros.ident.scenario import scenario_from_simulation
from phid_ros.ident.terminal import with_channels
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import Scenario
from test.io.field.field_sets import NO_LOAD


def test_field_and_torque_steps_give_the_network_s_reactance_and_no_load_gives_none() -> None:
    cfg = SimulationConfig()
    x_e = cfg.network.x_transformer + cfg.network.x_line
    field, torque = (
        scenario_from_simulation(r, r.measured)
        for r in simulate_scenarios(
            [Scenario("field", "field_step", 1.1, duration=8.0), Scenario("torque", "torque_step", 0.05, duration=8.0)],
            cfg,
        )
    )
    found = thevenin_reactance(field)
    assert found is not None
    assert found.x_e == pytest.approx(x_e, rel=0.03)
    # the source behind it holds still: most of V_t's movement is the drop across X_e
    assert found.source_spread < 0.2 * found.terminal_spread
    assert f"X_e = {found.x_e:.3f} pu" in found.describe()
    # a torque step moves P and, through the load angle, Q a little: through the sensors' noise
    # (averaged over 0.1 s) the same reactance
    moved = thevenin_reactance(torque)
    assert moved is not None and moved.x_e == pytest.approx(x_e, rel=0.03)
    [run] = simulate_scenarios([Scenario("open", "field_step", 1.1, duration=8.0)], dataclasses.replace(NO_LOAD))
    assert thevenin_reactance(scenario_from_simulation(run, run.measured)) is None
    still = with_channels(field, {"q_e": np.full(field.n, 0.3)}, "Q held")
    assert thevenin_reactance(still) is None
