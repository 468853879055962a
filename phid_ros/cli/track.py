"""``phid track``: the sliding-window tracker over a recording, hop by hop."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from rich.markup import escape

from phid_ros.cli.common import read_input, warn
from phid_ros.cli.identify import load_parameters
from phid_ros.cli.monitor_report import HealthLog
from phid_ros.cli.progress import ProgressLine
from phid_ros.cli.tables import CONCISE_LEGEND, estimate_text
from phid_ros.errors import PhidError
from phid_ros.io.bags import write_messages
from phid_ros.io.outputs import atomic_output
from phid_ros.io.topics import OUTPUT_TOPICS, output_topic
from phid_ros.model.conventions import NS
from phid_ros.model.parameters import SYMBOLS, TABLE1, GeneratorParameters
from phid_ros.stream.replay import track_recording
from phid_ros.stream.tracker import TRACKED, TrackerSettings, TrackPoint


def health_over_time(rec: Any, bin_s: float) -> HealthLog:
    """Each stream's completeness per ``bin_s`` of the recording, from its stamps.

    Level per bin: OK with 99 % of the expected samples, WARN with 90 %, ERROR below,
    STALE with none; the counters are the samples missing, the gaps and the backward
    stamps since the start.
    """
    import numpy as np

    start, end = rec.span_ns()
    edges = np.arange(start, end + int(bin_s * NS), int(bin_s * NS))
    log = HealthLog(t_s=[float(t) for t in (edges[1:] - start) / NS])
    for name, s in rec.streams.items():
        got = np.histogram(s.t_ns, edges)[0]
        # the last bin may be cut by the end of the recording: expect only what it spans
        expected = (np.minimum(edges[1:], end + s.period_ns) - edges[:-1]) / s.period_ns
        share = got / expected
        step = np.diff(s.t_ns)
        gap_at = s.t_ns[1:][step > 1.5 * s.period_ns]
        back_at = s.t_ns[1:][step <= 0]
        missing = np.cumsum(np.maximum(0, np.round(expected) - got)).astype(int)
        gaps = np.cumsum(np.histogram(gap_at, edges)[0])
        jumps = np.cumsum(np.histogram(back_at, edges)[0])
        levels = np.where(share >= 0.99, "OK", np.where(share >= 0.9, "WARN", np.where(share > 0, "ERROR", "STALE")))
        log.streams[name] = [(str(lv), int(m), int(g), int(j)) for lv, m, g, j in zip(levels, missing, gaps, jumps)]
    return log


def hop_line(start_ns: int, p: TrackPoint) -> str:
    """One hop on one line of at most 80 columns: the window's end, then the six tracked values."""
    cells = []
    for n in TRACKED:
        e = p.estimates.get(n)
        cells.append(f"{estimate_text(e.value, e.std, e.identifiable) if e else '—':>11}")
    return f"{(p.t_ns - start_ns) / NS:>7.0f} " + " ".join(cells)


def base_parameters(args: Any) -> GeneratorParameters:
    if not args.base:
        warn(
            f"no --base: X_d and X_q are the paper's Table 1 values ({TABLE1.X_d:g}, {TABLE1.X_q:g} pu), "
            "not this machine's; "
            "give --base PARAMS.json (phid identify --json) for real data"
        )
        return TABLE1
    return load_parameters(args.base)


def run(args: Any, console: Any) -> int:
    if args.hop > args.window:
        raise PhidError(f"--hop {args.hop:g} s is longer than --window {args.window:g} s: samples would be skipped")
    from phid_ros.io.outputs import refuse_inputs

    refuse_inputs([args.out, args.report], [args.bag, args.base])
    if args.out:
        if Path(args.out).exists():
            raise PhidError(f"{args.out}: already exists, not overwriting")
    base = base_parameters(args)  # checked before the recording is read
    with ProgressLine(f"reading {args.bag}"):
        rec, _ = read_input(args.bag)
    start = rec.span_ns()[0]
    console.print(f"sliding-window tracking ({args.window:g} s window, {args.hop:g} s hop)", highlight=False)
    console.print(escape(CONCISE_LEGEND), style="dim", highlight=False)
    console.print(f"{'t s':>7} " + " ".join(f"{SYMBOLS[n]:>11}" for n in TRACKED), highlight=False)

    end = rec.span_ns()[1]

    def show(p: TrackPoint) -> None:
        console.print(hop_line(start, p), highlight=False)
        for a in p.alarms:
            console.print(f"{'':>8}alarm: {a}", style="bold red", highlight=False, markup=False)
        progress.update(f"tracking: {(p.t_ns - start) / NS:.0f} of {(end - start) / NS:.0f} s")

    t0 = time.perf_counter()
    with ProgressLine("tracking: the first window") as progress:
        points = track_recording(rec, base, TrackerSettings(window_s=args.window, hop_s=args.hop), show)
    wall = time.perf_counter() - t0
    if not points:
        raise PhidError(f"{args.bag}: shorter than one tracking window ({args.window:g} s)")
    alarmed = sorted({n for p in points for n in p.alarmed})
    console.print(
        f"{len(points)} hops; alarms raised for: {', '.join(SYMBOLS[n] for n in alarmed) or 'none'}; "
        f"tracked in {wall:.1f} s (wall time)",
        highlight=False,
    )
    if args.report:
        from phid_ros.cli.monitor_report import write_track_report

        notes = [] if args.base else ["X_d and X_q: the paper's Table 1 values (no --base given)"]
        notes += sorted({q for p in points for q in p.problems})
        with ProgressLine(f"writing {args.report}"):
            write_track_report(
                args.report,
                rec,
                points,
                health_over_time(rec, args.hop),
                str(args.bag),
                notes,
                f"{args.window:g} s window, {args.hop:g} s hop, {len(points)} hops",
            )
        console.print(f"wrote {args.report}", highlight=False)
    if args.out:
        from phid_ros.io.msg_schemas import typestore
        from phid_ros.stream.messages import tracked_message

        types = typestore().types
        topic, msgtype = output_topic("tracked_parameters"), OUTPUT_TOPICS["tracked_parameters"][1]
        msgs = [(p.t_ns, topic, msgtype, tracked_message(types, p)) for p in points]
        with atomic_output(args.out) as tmp:
            write_messages(tmp, msgs)
        console.print(f"wrote {len(msgs)} messages to {args.out}", highlight=False)
    return 0
