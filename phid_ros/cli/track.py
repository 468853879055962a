"""``phid track``: the sliding-window tracker over a recording, hop by hop."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from rich.table import Table

from phid_ros.cli.common import read_input
from phid_ros.errors import PhidError
from phid_ros.io.bags import write_messages
from phid_ros.io.outputs import atomic_output
from phid_ros.io.recording import NS
from phid_ros.io.results import read_json
from phid_ros.model.parameters import TABLE1, GeneratorParameters
from phid_ros.stream.align import Aligner
from phid_ros.stream.tracker import TRACKED, SlidingTracker, TrackerSettings, TrackPoint


def track_recording(rec: Any, tracker: SlidingTracker) -> list[TrackPoint]:
    """Align the recording's streams and feed the tracker in one pass (segments respected)."""
    aligner = Aligner(rec.streams["pt_ct"].period_ns)
    for name, s in rec.streams.items():
        if _uniform(s):
            aligner.ingest(name, int(s.t_ns[0]), s.period_ns, s.channels)
        else:
            _ingest_blocks(aligner, name, s)
    points: list[TrackPoint] = []
    segment = 0
    chunk = max(1, int(10 * NS // rec.streams["pt_ct"].period_ns))  # 10 s at a time: the ring holds one window
    for block in aligner.pull(final=True):
        if block.segment != segment:
            segment = block.segment
            tracker.reset()
        for k in range(0, len(block.t_ns), chunk):
            points += tracker.update(block.t_ns[k : k + chunk], block.values[k : k + chunk])
    return points


def _uniform(s: Any) -> bool:
    import numpy as np

    return bool(len(s.t_ns) < 2 or np.all(np.diff(s.t_ns) == s.period_ns))


def _ingest_blocks(aligner: Aligner, name: str, s: Any) -> None:
    from phid_ros.io.recording import block_bounds

    for a, b in block_bounds(s.t_ns, s.period_ns, 1_000_000):
        aligner.ingest(name, int(s.t_ns[a]), s.period_ns, {c: v[a:b] for c, v in s.channels.items()})


def base_parameters(args: Any) -> GeneratorParameters:
    if not args.base:
        return TABLE1
    doc = read_json(args.base)
    values = doc.get("parameters", doc)
    if not isinstance(values, dict):
        raise PhidError(f"{args.base}: 'parameters' must be an object of the eight parameters")
    return GeneratorParameters.from_mapping(values, source=args.base)


def run(args: Any, console: Any) -> int:
    if args.hop > args.window:
        raise PhidError(f"--hop {args.hop:g} s is longer than --window {args.window:g} s: samples would be skipped")
    if args.out:
        from phid_ros.io.outputs import refuse_inputs

        refuse_inputs([args.out], [args.bag, args.base])
        if Path(args.out).exists():
            raise PhidError(f"{args.out}: already exists, not overwriting")
    base = base_parameters(args)  # checked before the recording is read
    rec, _ = read_input(args.bag)
    tracker = SlidingTracker(
        base, rec.streams["pt_ct"].period_ns, TrackerSettings(window_s=args.window, hop_s=args.hop)
    )
    t0 = time.perf_counter()
    points = track_recording(rec, tracker)
    wall = time.perf_counter() - t0
    if not points:
        raise PhidError(f"{args.bag}: shorter than one tracking window ({args.window:g} s)")
    start = rec.span_ns()[0]
    table = Table(title=f"sliding-window tracking ({args.window:g} s window, {args.hop:g} s hop)", title_justify="left")
    table.add_column("t s", justify="right")
    for n in TRACKED:
        table.add_column(n, justify="right")
    table.add_column("alarm")
    for p in points:
        cells = []
        for n in TRACKED:
            e = p.estimates.get(n)
            if e is None or not math.isfinite(e.value):
                cells.append("—")
            else:
                cells.append(f"{e.value:.4g}±{e.std:.1g}" + ("" if e.identifiable else " ?"))
        table.add_row(f"{(p.t_ns - start) / NS:.0f}", *cells, "; ".join(p.alarms)[:60])
    console.print(table)
    console.print(
        f"{len(points)} hops in {wall:.1f} s; alarms raised for: {', '.join(sorted(tracker.alarmed)) or 'none'}"
        " ('?' = not identifiable in that window)",
        highlight=False,
    )
    if args.out:
        from phid_ros.io.msg_schemas import typestore
        from phid_ros.stream.messages import header

        types = typestore().types
        import numpy as np

        msgs = []
        for p in points:
            names = [n for n in TRACKED if n in p.estimates]
            msgs.append(
                (
                    p.t_ns,
                    "/phid/tracked_parameters",
                    "phid_msgs/msg/GeneratorParameters",
                    types["phid_msgs/msg/GeneratorParameters"](
                        header=header(types, p.t_ns),
                        names=names,
                        values=np.array([p.estimates[n].value for n in names]),
                        std_dev=np.array([p.estimates[n].std for n in names]),
                        identifiable=np.array([p.estimates[n].identifiable for n in names], dtype=bool),
                        method="tracker",
                        event_ids=[],
                        objective=math.nan,
                        fit_rmse=math.nan,
                        status="; ".join(p.alarms) or "ok",
                    ),
                )
            )
        with atomic_output(args.out) as tmp:
            write_messages(tmp, msgs)
        console.print(f"wrote {len(msgs)} messages to {args.out}", highlight=False)
    return 0
