"""Shared fixtures: short simulations and the recordings made from them."""

from __future__ import annotations

import pytest

from phid_ros.io.recording import Recording
from phid_ros.sim.recording import recording_from_runs
from phid_ros.sim.runner import ScenarioRun, SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import Scenario, paper_catalogue

# The rclpy test double is a set of packages, not tests: pytest 7 (the ROS venv's) imports a
# collected package's __init__ under its bare name, which put the double's `rclpy` into
# sys.modules for the whole session and broke the real launch test under colcon test.
collect_ignore = ["rclpy_double"]


@pytest.fixture(scope="session", autouse=True)
def one_blas_thread():
    """The tests run as the commands do, with one BLAS thread (``phid_ros.cluster.one_blas_thread``):
    the same digits, and two test workers on two cores do not spin on each other's cores."""
    from phid_ros.cluster import one_blas_thread

    with one_blas_thread():
        yield


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


def scenario_from_run(run: ScenarioRun, *, noisy: bool = True):
    """ScenarioData straight from a simulated run (analysis window only)."""
    from phid_ros.ident.scenario import scenario_from_simulation

    return scenario_from_simulation(run, run.measured if noisy else run.truth)


@pytest.fixture(scope="session")
def catalogue_runs() -> list[ScenarioRun]:
    """The paper catalogue with 12 s windows (10 s for validation), sensor seed 0."""
    from dataclasses import replace

    cat = [replace(s, duration=12.0 if s.role == "identify" else 10.0) for s in paper_catalogue()]
    return simulate_scenarios(cat, SimulationConfig(restore_ramp=1.0, restore_hold=1.0))


@pytest.fixture(scope="session")
def noisy_scenarios(catalogue_runs):
    return [scenario_from_run(r) for r in catalogue_runs]


@pytest.fixture(scope="session")
def clean_scenarios(catalogue_runs):
    return [scenario_from_run(r, noisy=False) for r in catalogue_runs]
