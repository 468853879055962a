"""Simulator and bag I/O speed: prints medians over repeats, and peak memory.

    python benchmarks/bench_simulate.py [--repeats 3]

Baseline for the vectorised run: the same scenarios simulated one at a time.
"""

from __future__ import annotations

import argparse
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import median_time as timed  # noqa: E402

from phid_ros.io.bags.recordings import read_recording, write_recording
from phid_ros.sim.recording import recording_from_runs
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import paper_catalogue


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    cfg = SimulationConfig()
    cat = paper_catalogue()
    t_vec, runs = timed(lambda: simulate_scenarios(cat, cfg), args.repeats)
    t_one, _ = timed(lambda: [simulate_scenarios([s], cfg) for s in cat], 1)
    rec = recording_from_runs(runs, cfg)
    samples = sum(len(s) * len(s.channels) for s in rec.streams.values())
    tmp = Path(tempfile.mkdtemp())
    try:

        def write(kind: str) -> Path:
            p = tmp / f"b{time.perf_counter_ns()}{kind}"
            return write_recording(p, rec)

        t_w2, p2 = timed(lambda: write(""), args.repeats)
        t_wm, pm = timed(lambda: write(".mcap"), args.repeats)
        t_r2, _ = timed(lambda: read_recording(p2), args.repeats)
        t_rm, _ = timed(lambda: read_recording(pm), args.repeats)
        size2 = sum(f.stat().st_size for f in Path(p2).rglob("*") if f.is_file())
    finally:
        shutil.rmtree(tmp)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    seconds = len(rec.streams["pt_ct"]) / 1000
    print(f"catalogue: {len(cat)} scenarios, {samples / 1e6:.2f} M channel-samples ({seconds:.0f} s at 1 kHz)")
    print(f"simulate, vectorised over scenarios : {t_vec:6.2f} s (median of {args.repeats})")
    print(f"simulate, one scenario at a time    : {t_one:6.2f} s  -> vectorised is {t_one / t_vec:.1f}x faster")
    print(f"write rosbag2 (mcap, zstd)          : {t_w2:6.2f} s, {size2 / 1e6:.1f} MB")
    print(f"write .mcap                         : {t_wm:6.2f} s")
    print(f"read rosbag2                        : {t_r2:6.2f} s ({samples / t_r2 / 1e6:.1f} M channel-samples/s)")
    print(f"read .mcap                          : {t_rm:6.2f} s ({samples / t_rm / 1e6:.1f} M channel-samples/s)")
    print(f"peak resident memory                : {peak_mb:.0f} MB")


if __name__ == "__main__":
    main()
