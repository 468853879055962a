"""The monitor on a recorder's channels: what carrying the field current and fitting the exciter cost.

    python benchmarks/bench_monitor_field.py [--runs 3] [--bag DAY.mcap --fix X_q=0.62 --saturation 0.1,0.4]

Replays a commissioning day through the online pipeline three ways, alternated run by run (a
noisy machine slows all alike), and prints each one's median wall time, its ratio to the first
(the baseline, in the same run), the partial set its last recalibration published, and the peak
resident memory of the process:

- ``sensors only``: the field controller's stream left out, no control system fitted (the
  pipeline before the recorder's channels were carried);
- ``with I_fd``: the field controller's stream kept and handed to each window;
- ``with I_fd + controls``: and the exciter and the stabiliser fitted at each recalibration (the
  nodes' default).

Without ``--bag``, the simulated day of trend logs (the TABLE 1 machine: a no-load field step,
four on-line field steps, two grid steps at 208 reports/s; X_q held).
"""

from __future__ import annotations

import argparse
import dataclasses
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from phid_ros.api import load_recording  # noqa: E402
from phid_ros.ident.constraints import parse_constraints  # noqa: E402
from phid_ros.ident.pipeline import IdentifyOptions  # noqa: E402
from phid_ros.io.recording import Recording, not_recorded  # noqa: E402
from phid_ros.io.topics import RECORDER_STREAMS  # noqa: E402
from phid_ros.model.parameters import SYMBOLS, TABLE1  # noqa: E402
from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings  # noqa: E402
from phid_ros.stream.replay import replay  # noqa: E402

WAYS = ("sensors only", "with I_fd", "with I_fd + controls")


def replay_once(rec: Recording, way: str, options: IdentifyOptions) -> tuple[float, str]:
    """Wall time of one replay and its last partial set, as text."""
    if way == "sensors only":
        rec = dataclasses.replace(rec, streams={n: s for n, s in rec.streams.items() if n not in {"field_controller"}})
    settings = PipelineSettings(
        period_ns=rec.streams["pt_ct"].period_ns,
        not_recorded=not_recorded(rec.metadata),
        identify=options,
        control_systems=("exciter", "stabiliser") if way.endswith("controls") else (),
    )
    pipeline = MonitorPipeline(settings)
    try:
        t0 = time.perf_counter()
        out = replay(rec, pipeline)
        wall = time.perf_counter() - t0
    finally:
        pipeline.close()
    last = next((r for r in reversed(out.recalibrations) if r.determined), None)
    said = ", ".join(f"{SYMBOLS[n]} {e.value:.5g}" for n, e in last.determined.items()) if last else "none"
    return wall, said


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--bag", type=Path, help="a commissioning day's import (default: the simulated trend logs)")
    ap.add_argument("--fix", action="append", default=None, help="NAME=VALUE held, as phid identify --fix")
    ap.add_argument("--saturation", help="S(1.0),S(1.2), as phid identify --saturation")
    args = ap.parse_args()
    assert {s.name for s in RECORDER_STREAMS} == {"field_controller"}
    with tempfile.TemporaryDirectory() as tmp:
        if args.bag is None:
            from phid_ros.io.bags.recordings import write_recording
            from phid_ros.io.field.channel_map import load_channel_map
            from phid_ros.io.field.pmu_csv import import_pmu_csv
            from test.io.field.field_sets import trend_log_set

            paths, cmap = trend_log_set(Path(tmp), TABLE1)
            bag = Path(tmp) / "day.mcap"
            write_recording(bag, import_pmu_csv(paths, [load_channel_map(cmap)]))
            fixes = args.fix or [f"X_q={TABLE1.X_q}"]
        else:
            bag, fixes = args.bag, args.fix or []
        rec = load_recording(bag)
        options = IdentifyOptions(baseline=False, constraints=parse_constraints(fixes, saturation=args.saturation))
        times: dict[str, list[float]] = {w: [] for w in WAYS}
        said = {}
        for _ in range(args.runs):
            for way in WAYS:
                wall, said[way] = replay_once(rec, way, options)
                times[way].append(wall)
    stream_s = (rec.span_ns()[1] - rec.span_ns()[0]) / 1e9
    base = statistics.median(times[WAYS[0]])
    print(f"{bag.name}: {stream_s:.0f} s of stream time, medians of {args.runs} run(s):")
    for way in WAYS:
        m = statistics.median(times[way])
        print(f"  {way:22s} {m:7.2f} s  ({m / base:.2f}x)  last partial set: {said[way]}")
    print(f"peak memory {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()
