"""CSV scenario sets from an independent salient-pole plant: STEPS's GENSAL on phid's single-machine case.

    python benchmarks/steps_sets.py --machine gensal-sat --out sets/gensal_sat [--duration 12] [--seed 0]

Machines (``test/steps_plant.py``, machine base 1000 MVA on a 100 MVA system base): ``gensal``
(a hydro unit's salient-pole data, X'' 0.22, T''_d0 0.05 s, T''_q0 0.08 s), ``gensal-sat`` (the
same with S(1.0) 0.1, S(1.2) 0.4, PSS/E's GENSAL saturation: on E'_q, d axis only),
``gensal-controls`` and ``gensal-sat-controls`` (with SEXS and TGOV1 in the loop: a field step is a
voltage-reference step, a torque step a load-reference step). Scenarios: the paper's catalogue
(15 for identification, 3 validation) with the simulator's sensor noise; ``phid identify`` and
``phid diagnose`` read the set's manifest.json. STEPS is built from its source first:
``benchmarks/steps_build.sh``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from phid_ros.sim.scenarios import paper_catalogue, with_duration  # noqa: E402
from test.steps_plant import MACHINES, TRUTH, write_set  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machine", choices=sorted(MACHINES), required=True)
    ap.add_argument("--out", required=True, help="the set's folder (manifest.json and one CSV per scenario)")
    ap.add_argument("--duration", type=float, default=12.0, help="seconds per scenario (default 12)")
    ap.add_argument("--seed", type=int, default=0, help="sensor-noise seed")
    ap.add_argument("--noise", type=float, default=1.0, help="times the simulator's sensor noise")
    args = ap.parse_args()
    scenarios = [with_duration(s, args.duration) for s in paper_catalogue()]
    t0 = time.perf_counter()
    machine = MACHINES[args.machine]
    manifest = write_set(Path(args.out), machine, scenarios, seed=args.seed, noise=args.noise)
    out = Path(args.out)
    truth = out.with_suffix(".truth.json") if out.suffix else Path(f"{args.out}.truth.json")
    truth.write_text(
        json.dumps({"parameters": TRUTH[args.machine], "steps": asdict(machine), "dyr": machine.dyr()}, indent=1)
    )
    seconds = time.perf_counter() - t0
    print(f"wrote {manifest} and {truth}: {len(scenarios)} scenarios of {args.machine} in {seconds:.0f} s")


if __name__ == "__main__":
    main()
