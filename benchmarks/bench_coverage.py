"""Do the reported standard deviations cover the errors? A coverage study over sensor-noise seeds.

    python benchmarks/bench_coverage.py [--seeds 20] [--json out.json]

The plant is simulated once (noise-free); each seed draws new sensor noise on it, and the
identification runs on three scenario sets: the paper catalogue, the torque steps only,
and a single torque step. For every parameter reported *identifiable* it counts how
often the truth lies within 2 sigma of the estimate (about 95 % for an honest Gaussian
sigma; the goal is at least 90 %), and how often the parameter was flagged instead.
Prints the table, the wall time, and optionally writes the figures as JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from phid_ros.ident.pipeline import IdentifyOptions, identify
from phid_ros.ident.scenario import scenario_from_simulation
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import paper_catalogue
from phid_ros.sim.sensors import SensorModel

SETS = {
    "catalogue": lambda sc: True,
    "torque steps only": lambda sc: sc.kind == "torque_step",
    "one torque step": lambda sc: sc.name.startswith("S04"),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args()
    t0 = time.perf_counter()
    cfg = SimulationConfig(sensors=SensorModel(noiseless=True))
    runs = simulate_scenarios([s for s in paper_catalogue() if s.role == "identify"], cfg)
    truth = TABLE1.as_dict()
    opts = IdentifyOptions(baseline=False, validate=False)
    # per set, per parameter: [identifiable and covered, identifiable, flagged] and the z-scores
    tally = {s: {n: [0, 0, 0] for n in PARAMETER_NAMES} for s in SETS}
    zs: dict[str, dict[str, list[float]]] = {s: {n: [] for n in PARAMETER_NAMES} for s in SETS}
    for seed in range(args.seeds):
        sensors = SensorModel(seed=1000 + seed)
        noisy = [scenario_from_simulation(r, sensors.measure(r.truth, stream_seed=j)) for j, r in enumerate(runs)]
        for set_name, keep in SETS.items():
            res = identify([s for s, r in zip(noisy, runs) if keep(r.scenario)], opts)
            for n in PARAMETER_NAMES:
                est = res.estimates.get(n)
                if est is None or not math.isfinite(est.value):
                    continue
                t = tally[set_name][n]
                if not est.identifiable:
                    t[2] += 1
                    continue
                z = (est.value - truth[n]) / est.std if est.std > 0 else math.inf
                zs[set_name][n].append(z)
                t[1] += 1
                t[0] += int(abs(z) <= 2.0)
    wall = time.perf_counter() - t0
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"coverage of ±2σ over {args.seeds} noise seeds (identifiable estimates only)")
    table.add_column("set")
    for n in PARAMETER_NAMES:
        table.add_column(n, justify="right")
    worst = 1.0
    for set_name in SETS:
        row = [set_name]
        for n in PARAMETER_NAMES:
            covered, ident, flagged = tally[set_name][n]
            if ident:
                worst = min(worst, covered / ident)
                cell = f"{100 * covered / ident:.0f} % of {ident}"
            else:
                cell = "—"
            if flagged:
                cell += f" ({flagged} flagged)"
            row.append(cell)
        table.add_row(*row)
    console = Console(width=200)
    console.print(table)
    console.print(
        f"worst coverage of an identifiable parameter: {100 * worst:.0f} % (goal >= 90 %); "
        f"median |z| per set: "
        + "; ".join(
            f"{s}: " + ", ".join(f"{n} {np.median(np.abs(zs[s][n])):.2f}" for n in PARAMETER_NAMES if zs[s][n])
            for s in SETS
        ),
        highlight=False,
    )
    console.print(f"wall time {wall:.1f} s", highlight=False)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"seeds": args.seeds, "tally": tally, "z": zs, "worst": worst, "wall_s": wall}, fh, indent=1)


if __name__ == "__main__":
    main()
