"""Shared set-up for the benchmark scripts: the shipped catalogue as identification scenarios."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from phid_ros.ident.scenario import ScenarioData
from phid_ros.io.bags import read_recording
from phid_ros.stream.scenarios import scenarios_from_recording

ROOT = Path(__file__).resolve().parents[1]
CATALOGUE = ROOT / "bags" / "catalogue"


def catalogue_scenarios(path: Path = CATALOGUE) -> list[ScenarioData]:
    scs, _ = scenarios_from_recording(read_recording(path), str(path))
    return scs


T = TypeVar("T")


def median_time(fn: Callable[[], T], repeats: int) -> tuple[float, T]:
    """The median wall time of ``repeats`` calls (at least one), and the last call's result."""
    t0 = time.perf_counter()
    out = fn()
    times = [time.perf_counter() - t0]
    for _ in range(repeats - 1):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out
