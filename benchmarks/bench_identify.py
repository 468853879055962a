"""Whole identification from bag to JSON: ``phid identify`` on the shipped catalogue bag.

    python benchmarks/bench_identify.py [--runs 7]

Each run is a fresh ``phid identify`` process; the figure is the command's own
timing from the start of reading the bag to the written JSON (library imports
done lazily inside that span are included; interpreter start-up is not). Also
prints the same work repeated inside one warm process, and peak memory.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--bag", default=str(ROOT / "bags" / "catalogue"))
    args = ap.parse_args()
    totals, stages = [], []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "r.json"
        for _ in range(args.runs):
            subprocess.run(
                [sys.executable, "-m", "phid_ros.cli.main", "identify", args.bag, "--json", str(out)],
                check=True,
                capture_output=True,
            )
            doc = json.loads(out.read_text())
            totals.append(doc["timing_s"]["total"])
            stages.append(doc["timing_s"])
    print(f"phid identify {args.bag} -> JSON, {args.runs} fresh processes:")
    print(f"  total: median {statistics.median(totals):.3f} s (min {min(totals):.3f}, max {max(totals):.3f})")
    for key in stages[0]:
        if key != "total":
            print(f"  {key:11s} median {statistics.median(s[key] for s in stages):.3f} s")

    from phid_ros.ident.pipeline import IdentifyOptions, identify
    from phid_ros.io.bags.recordings import read_recording
    from phid_ros.io.files.results import write_json
    from phid_ros.stream.scenarios import scenarios_from_recording

    warm = []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.runs):
            t0 = time.perf_counter()
            rec = read_recording(args.bag)
            scs, _ = scenarios_from_recording(rec, args.bag)
            res = identify(scs, IdentifyOptions(f_nominal_hz=rec.f_nominal_hz))
            write_json(Path(tmp) / "r.json", res.to_json())
            warm.append(time.perf_counter() - t0)
    print(f"  same work in one warm process: median {statistics.median(warm):.3f} s over {args.runs}")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"  peak resident memory of the warm process: {peak_mb:.0f} MB")


if __name__ == "__main__":
    main()
