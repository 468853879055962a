"""Shared fixtures: short simulations and the recordings made from them."""

from __future__ import annotations

import pytest

from phid_ros.cli.simulate import recording_from_runs
from phid_ros.io.recording import Recording
from phid_ros.sim.runner import ScenarioRun, SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import Scenario, paper_catalogue


def short(name: str, duration: float = 4.0) -> Scenario:
    from dataclasses import replace

    sc = next(s for s in paper_catalogue() if s.name.startswith(name))
    return replace(sc, duration=duration)


@pytest.fixture(scope="session")
def short_config() -> SimulationConfig:
    return SimulationConfig(restore_ramp=1.0, restore_hold=1.0)


@pytest.fixture(scope="session")
def short_runs(short_config: SimulationConfig) -> list[ScenarioRun]:
    """A torque step, a voltage step and a fault, 4 s each (plus 2 s restore)."""
    return simulate_scenarios([short("S04"), short("S10"), short("S15")], short_config)


@pytest.fixture(scope="session")
def short_recording(short_runs: list[ScenarioRun], short_config: SimulationConfig) -> Recording:
    return recording_from_runs(short_runs, short_config)
