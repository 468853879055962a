"""``phid``: simulate, import-csv, info.

Errors caused by input (missing file, bad column, truncated bag, ...) are
printed on one line as ``phid: error: ...`` with exit status 2, no traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from phid_ros import __version__
from phid_ros.errors import PhidError
from phid_ros.io.recording import DEFAULT_BLOCK_SIZE

EXIT_USER_ERROR = 2


def _progress(console: Console) -> Progress:
    return Progress(
        SpinnerColumn(),
        TextColumn("{task.description}"),
        BarColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )


# -- simulate ------------------------------------------------------------------
def _parse_effects(items: Sequence[str]) -> list[str]:
    if items:
        raise PhidError(f"plant effects {list(items)} are not available yet; the base model has none switched on")
    return []


def cmd_simulate(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.simulate import recording_from_runs, truth_document
    from phid_ros.io.bags import write_recording
    from phid_ros.io.results import truth_path_for, write_json
    from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
    from phid_ros.sim.scenarios import find_scenario, paper_catalogue, validation_scenarios
    from phid_ros.sim.sensors import SensorModel

    _parse_effects(args.effect or [])
    if args.scenario:
        scenarios = [find_scenario(name) for name in args.scenario]
    elif args.catalogue == "validation":
        scenarios = validation_scenarios()
    else:
        scenarios = paper_catalogue()
    if args.duration is not None:
        from phid_ros.sim.scenarios import with_duration

        scenarios = [with_duration(s, args.duration) for s in scenarios]
    out = Path(args.out)
    if out.exists():
        raise PhidError(f"{out}: already exists, not overwriting")
    cfg = SimulationConfig(f_nominal_hz=args.f_nominal, sensors=SensorModel(seed=args.seed, noiseless=args.noiseless))
    with _progress(console) as progress:
        task = progress.add_task(f"simulating {len(scenarios)} scenario(s)", total=None)
        runs = simulate_scenarios(scenarios, cfg)
        progress.update(task, description=f"writing {out}")
        rec = recording_from_runs(runs, cfg)
        write_recording(out, rec, block_size=args.block_size)
    truth = write_json(truth_path_for(out), truth_document(cfg, scenarios))
    start, end = rec.span_ns()
    console.print(f"wrote {out} ({len(scenarios)} scenarios, {(end - start) / 1e9:.1f} s of data) and {truth}")
    return 0


# -- import-csv ------------------------------------------------------------------
def cmd_import_csv(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.bags import write_recording
    from phid_ros.io.csv_import import import_csv_set

    out = Path(args.out)
    if out.exists():
        raise PhidError(f"{out}: already exists, not overwriting")
    with _progress(console) as progress:
        progress.add_task(f"importing {args.manifest}", total=None)
        rec, warnings = import_csv_set(args.manifest, strict=args.strict)
        write_recording(out, rec, block_size=args.block_size)
    for w in warnings:
        console.print(f"[yellow]warning:[/] {w}", highlight=False)
    console.print(f"wrote {out} ({len(rec.scenarios)} scenarios)")
    return 0


# -- info --------------------------------------------------------------------------
def _iso(ns: int) -> str:
    return datetime.fromtimestamp(ns / 1e9, tz=timezone.utc).isoformat(timespec="milliseconds")


def cmd_info(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.info import summarise_streams
    from phid_ros.io.bags import read_recording, topic_table
    from phid_ros.io.recording import expected_type

    path = Path(args.bag)
    topics = topic_table(path)
    if not any(expected_type(t) for t, _, _ in topics):
        # an output bag (phid replay) or foreign data: the topic table is all there is to show
        table = Table(title=f"{path} (no sensor streams)", title_justify="left")
        for col in ("topic", "type", "messages"):
            table.add_column(col, justify="right" if col == "messages" else "left")
        for topic, msgtype, count in topics:
            table.add_row(topic, msgtype, str(count))
        console.print(table)
        return 0
    rec = read_recording(path)
    table = Table(title=f"{path}", title_justify="left")
    for col in ("topic", "type", "messages"):
        table.add_column(col, justify="right" if col == "messages" else "left")
    for topic, msgtype, count in topics:
        table.add_row(topic, msgtype, str(count))
    console.print(table)
    streams = Table(title="sensor streams", title_justify="left")
    for col in ("stream", "samples", "rate Hz", "start (UTC)", "span s", "gaps", "gap s", "backwards"):
        streams.add_column(col, justify="left" if col in ("stream", "start (UTC)") else "right")
    for s in summarise_streams(rec):
        streams.add_row(
            s.name,
            str(s.samples),
            f"{s.rate_hz:g}",
            _iso(s.start_ns),
            f"{(s.end_ns - s.start_ns) / 1e9:.3f}",
            str(s.gaps),
            f"{s.gap_seconds:.3f}",
            str(s.backwards),
        )
    console.print(streams)
    if rec.scenarios:
        sc_table = Table(title="scenarios", title_justify="left")
        for col in ("name", "kind", "role", "damping", "event s", "window s"):
            sc_table.add_column(col)
        t0 = rec.span_ns()[0]
        for sc in rec.scenarios:
            ev = f"{(sc.event_ns - t0) / 1e9:.3f}" if sc.event_ns else "?"
            sc_table.add_row(
                sc.name,
                sc.kind,
                sc.role,
                "yes" if sc.generator_damping else "no",
                ev,
                f"{(sc.end_ns - sc.start_ns) / 1e9:.1f}",
            )
        console.print(sc_table)
    if rec.metadata:
        console.print("metadata: " + ", ".join(f"{k}={v}" for k, v in sorted(rec.metadata.items())), highlight=False)
    return 0


# -- identify ------------------------------------------------------------------------
def cmd_identify(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.identify import run

    return run(args, console)


# -- replay --------------------------------------------------------------------------
def cmd_replay(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.replay import run

    return run(args, console)


# -- entry point -----------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="phid", description="Port-Hamiltonian generator identification.")
    parser.add_argument("--version", action="version", version=f"phid_ros {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("simulate", help="simulate the scenario catalogue (or some scenarios) into a bag")
    p.add_argument("--out", required=True, help="output: a rosbag2 folder, or a file ending in .mcap")
    p.add_argument(
        "--catalogue",
        choices=("paper", "validation"),
        default="paper",
        help="paper: 15 identification + 3 validation scenarios (default); validation: the 3 only",
    )
    p.add_argument(
        "--scenario", action="append", metavar="NAME", help="one scenario by name or id (S04, V3, ...); repeatable"
    )
    p.add_argument("--duration", type=float, help="override every scenario's analysis window, s")
    p.add_argument("--seed", type=int, default=0, help="sensor noise seed (default 0)")
    p.add_argument("--noiseless", action="store_true", help="write the true signals, no sensor noise")
    p.add_argument("--f-nominal", type=float, default=50.0, help="nominal frequency, Hz (default 50)")
    p.add_argument(
        "--block-size",
        type=int,
        default=DEFAULT_BLOCK_SIZE,
        help=f"samples per sensor message (default {DEFAULT_BLOCK_SIZE})",
    )
    p.add_argument("--effect", action="append", metavar="NAME[=k=v,...]", help="switch on a plant effect")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("import-csv", help="turn a CSV scenario set (manifest.json) into a bag")
    p.add_argument("manifest")
    p.add_argument("--out", required=True, help="output: a rosbag2 folder, or a file ending in .mcap")
    p.add_argument("--strict", action="store_true", help="refuse extra columns instead of ignoring them")
    p.add_argument(
        "--block-size",
        type=int,
        default=DEFAULT_BLOCK_SIZE,
        help=f"samples per sensor message (default {DEFAULT_BLOCK_SIZE})",
    )
    p.set_defaults(func=cmd_import_csv)

    p = sub.add_parser("identify", help="three-stage identification of the eight parameters")
    p.add_argument("input", help="rosbag2 folder, .mcap file, or CSV manifest.json")
    p.add_argument("--json", metavar="OUT", help="write the results JSON here")
    p.add_argument(
        "--method",
        choices=("fast", "paper"),
        default="fast",
        help="stage 3 optimiser: fast (variable projection, default) or paper (differential evolution)",
    )
    p.add_argument("--truth", metavar="TRUTH.json", help="true parameters (e.g. <bag>.truth.json) for errors")
    p.add_argument("--report", metavar="OUT.html", help="write a self-contained HTML report")
    p.add_argument("--no-baseline", action="store_true", help="skip the IEEE 115 baseline column")
    p.add_argument("--seed", type=int, default=0, help="seed of the stochastic optimisers (default 0)")
    p.add_argument("--paper-maxiter", type=int, default=300, help="generations of the paper's DE (default 300)")
    p.set_defaults(func=cmd_identify)

    p = sub.add_parser("replay", help="play a bag through the online pipeline (detection, recalibration, energy)")
    p.add_argument("bag", help="rosbag2 folder or .mcap file")
    p.add_argument("--out", required=True, help="output bag for every published message (.mcap or folder)")
    p.add_argument("--rate", type=float, help="play at R x real time (default: as fast as possible)")
    p.add_argument("--store", metavar="EVENTS.sqlite", help="keep the event store in this file (default: memory)")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("info", help="topics, message counts, rates, time span and gaps of a bag")
    p.add_argument("bag")
    p.set_defaults(func=cmd_info)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    console = Console() if sys.stdout.isatty() else Console(width=140, soft_wrap=True)
    try:
        return int(args.func(args, console))
    except PhidError as exc:
        print(f"phid: error: {exc}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print("phid: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
