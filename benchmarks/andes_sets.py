"""CSV scenario sets from an independent plant: ANDES's GENROU on phid's single-machine case.

    python benchmarks/andes_sets.py --machine genrou-sat --out sets/genrou_sat [--duration 30] [--seed 0]

Machines (``test/andes_plant.py``, machine base, Table 1 otherwise; the list there is whole): ``genrou-4th`` (X'_d =
X'_q = X'': exactly the fourth-order model), ``genrou-sat`` (the same with S(1.0) 0.07, S(1.2)
0.45, quadratic on the air-gap flux), ``genrou-sub`` (X'' 0.25, T''_d0 0.04 s, T''_q0 0.08 s),
``genrou-sat-sub`` (saturation and X'' 0.3, T''_d0 0.03 s, T''_q0 0.05 s). ANDES 2.0 has no
GENSAL. Scenarios: the paper's catalogue (15 for identification, 3 validation),
each simulated by ANDES with the simulator's sensor noise added; ``phid identify`` and
``phid diagnose`` read the set's manifest.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from phid_ros.sim.scenarios import paper_catalogue, with_duration  # noqa: E402
from test.andes_plant import MACHINES, TRUTH, write_set  # noqa: E402


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
    manifest = write_set(Path(args.out), MACHINES[args.machine], scenarios, seed=args.seed, noise=args.noise)
    truth = Path(args.out).with_suffix(".truth.json") if Path(args.out).suffix else Path(f"{args.out}.truth.json")
    truth.write_text(json.dumps({"parameters": TRUTH[args.machine], "andes_genrou": MACHINES[args.machine]}, indent=1))
    seconds = time.perf_counter() - t0
    print(f"wrote {manifest} and {truth}: {len(scenarios)} scenarios of {args.machine} in {seconds:.0f} s")


if __name__ == "__main__":
    main()
