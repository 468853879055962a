"""Online pipeline speed and memory: ``phid replay`` logic on the shipped catalogue and a long stream.

    python benchmarks/bench_replay.py [--repeats 3] [--long 1800]

Prints replay speed (x real time, recalibrations included), ingestion throughput
(channel-samples/s through alignment, ring buffer and detection, recalibration
off), and resident memory sampled along a long replay (it must stay flat).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import CATALOGUE  # noqa: E402

from phid_ros.io.bags.recordings import read_recording  # noqa: E402
from phid_ros.io.recording import Recording, StreamSamples  # noqa: E402
from phid_ros.io.topics import STREAMS  # noqa: E402
from phid_ros.model.conventions import NS
from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings  # noqa: E402
from phid_ros.stream.replay import replay  # noqa: E402


def rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096 / 2**20


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--long", type=float, default=1800.0, help="seconds of the long ambient stream")
    args = ap.parse_args()
    rec = read_recording(CATALOGUE)
    start, end = rec.span_ns()
    span = (end - start) / NS
    speeds, equal = [], []
    for _ in range(args.repeats):
        p = MonitorPipeline()
        t0 = time.perf_counter()
        replay(rec, p)
        speeds.append(span / (time.perf_counter() - t0))
        equal.append(p.parameters.as_dict() if p.parameters else None)
        p.close()
    rates = []
    for _ in range(args.repeats):
        p = MonitorPipeline(PipelineSettings(auto_recalibrate=False))
        p.recalibrator.finish = lambda stream_time_ns: []  # type: ignore[method-assign]
        t0 = time.perf_counter()
        replay(rec, p)
        rates.append(p.samples_in / (time.perf_counter() - t0))
        p.close()
    n_values = sum(len(s) * len(s.channels) for s in rec.streams.values())
    print(f"catalogue bag: {span:.0f} s of data, 4 streams, {n_values / 1e6:.1f} M channel-samples")
    print(
        f"  replay with recalibration : median {statistics.median(speeds):.0f}x real time "
        f"(min {min(speeds):.0f}x, max {max(speeds):.0f}x over {args.repeats})"
    )
    print(f"  ingestion, no recalibration: median {statistics.median(rates) / 1e6:.2f} M channel-samples/s")
    print(f"  final parameters identical across runs: {all(e == equal[0] for e in equal)}")

    import tempfile

    from phid_ros.sim.ambient import AmbientSettings, simulate_ambient

    run = simulate_ambient(AmbientSettings(duration_s=args.long))
    t_ns = (np.arange(len(run.t)) * 1_000_000).astype(np.int64)
    long = Recording(
        {s.name: StreamSamples(t_ns, 1_000_000, {c: run.measured[c] for c in s.channels}) for s in STREAMS}
    )
    del run
    for auto in (False, True):
        # a node keeps its events on disk, not in memory
        store = Path(tempfile.mkdtemp()) / "events.sqlite"
        p = MonitorPipeline(PipelineSettings(store_path=str(store), auto_recalibrate=auto))
        if not auto:
            p.recalibrator.finish = lambda stream_time_ns: []  # type: ignore[method-assign]
        series: list[tuple[float, float]] = []

        def watch(_out: object, p: MonitorPipeline = p, series: list = series) -> None:
            if p.latest_ns is not None and (not series or p.latest_ns / NS - series[-1][0] >= args.long / 6):
                series.append((p.latest_ns / NS, rss_mb()))

        t0 = time.perf_counter()
        replay(long, p, on_outputs=watch, keep_arrays=False)
        wall = time.perf_counter() - t0
        series.append((args.long, rss_mb()))
        label = "with recalibration" if auto else "ingestion only"
        print(
            f"long ambient stream, {label}: {args.long:.0f} s in {wall:.1f} s ({args.long / wall:.0f}x); resident "
            "memory " + ", ".join(f"{t:.0f} s {m:.0f} MB" for t, m in series)
        )
        p.close()


if __name__ == "__main__":
    main()
