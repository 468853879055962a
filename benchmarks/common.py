"""Shared set-up for the benchmark scripts: the shipped catalogue as identification scenarios."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

from phid_ros.ident.scenario import ScenarioData
from phid_ros.io.bags.recordings import read_recording
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


def plant_set_main(
    description: str,
    machines: Mapping[str, Any],
    write_set: Callable[..., Path],
    truth: Callable[[str], dict[str, Any]],
) -> None:
    """The command line of a set-writing script (andes_sets.py, steps_sets.py): one machine's
    set of the paper's catalogue as CSV, and its truth beside it (``truth(machine)``)."""
    import argparse
    import json

    from phid_ros.sim.scenarios import paper_catalogue, with_duration

    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--machine", choices=sorted(machines), required=True)
    ap.add_argument("--out", required=True, help="the set's folder (manifest.json and one CSV per scenario)")
    ap.add_argument("--duration", type=float, default=12.0, help="seconds per scenario (default 12)")
    ap.add_argument("--seed", type=int, default=0, help="sensor-noise seed")
    ap.add_argument("--noise", type=float, default=1.0, help="times the simulator's sensor noise")
    args = ap.parse_args()
    scenarios = [with_duration(s, args.duration) for s in paper_catalogue()]
    t0 = time.perf_counter()
    manifest = write_set(Path(args.out), machines[args.machine], scenarios, seed=args.seed, noise=args.noise)
    out = Path(args.out)
    path = out.with_suffix(".truth.json") if out.suffix else Path(f"{args.out}.truth.json")
    path.write_text(json.dumps(truth(args.machine), indent=1))
    seconds = time.perf_counter() - t0
    print(f"wrote {manifest} and {path}: {len(scenarios)} scenarios of {args.machine} in {seconds:.0f} s")
