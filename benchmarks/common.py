"""Shared set-up for the benchmark scripts: the shipped catalogue as identification scenarios."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from pathlib import Path

from phid_ros.ident.scenario import ScenarioData
from phid_ros.io.bags import read_recording
from phid_ros.stream.scenarios import scenarios_from_recording

ROOT = Path(__file__).resolve().parents[1]
CATALOGUE = ROOT / "bags" / "catalogue"


def catalogue_scenarios(path: Path = CATALOGUE) -> list[ScenarioData]:
    scs, _ = scenarios_from_recording(read_recording(path), str(path))
    return scs


def median_time(fn: Callable[[], object], repeats: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out
