"""What each ``phid`` command does, given its parsed arguments (the parser: :mod:`phid_ros.cli.parser`).

The longer commands live in their own modules (``cli/identify.py``, ``cli/replay.py``, ...),
imported when the command runs, so that ``phid --help`` does not load the identification.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path

from rich.console import Console
from rich.table import Table

from phid_ros.cli.common import warn, write_output
from phid_ros.cli.info import StreamTally
from phid_ros.cli.progress import ProgressLine
from phid_ros.cli.tables import Col, print_table
from phid_ros.errors import PhidError
from phid_ros.io.outputs import atomic_output, refuse_inputs
from phid_ros.io.recording import Recording
from phid_ros.model.conventions import NS, utc_of_stamp


# -- simulate ------------------------------------------------------------------
def _parse_effects(items: Sequence[str]) -> tuple:
    from phid_ros.sim.effects import parse_effect

    return tuple(parse_effect(item) for item in items)


def cmd_simulate(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.results import truth_path_for, write_json
    from phid_ros.sim.recording import recording_from_runs, truth_document
    from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
    from phid_ros.sim.scenarios import find_scenario, paper_catalogue, validation_scenarios
    from phid_ros.sim.sensors import SensorModel

    effects = _parse_effects(args.effect or [])
    if args.ambient and effects:
        raise PhidError("--effect is not available with --ambient yet (the long-run integrator has no effect hooks)")
    if args.ambient:
        return _simulate_ambient(args, console)
    if args.drift:
        raise PhidError("--drift needs --ambient (a drift happens over a long run)")
    if args.scenario:
        scenarios = [find_scenario(name) for name in args.scenario]
    elif args.catalogue == "validation":
        scenarios = validation_scenarios()
    else:
        scenarios = paper_catalogue()
    if args.duration is not None:
        from phid_ros.sim.scenarios import with_duration

        scenarios = [with_duration(s, args.duration) for s in scenarios]
    out = _simulation_output(args)
    cfg = SimulationConfig(
        f_nominal_hz=args.f_nominal, sensors=SensorModel(seed=args.seed, noiseless=args.noiseless), effects=effects
    )
    with ProgressLine(f"simulating {len(scenarios)} scenario(s)") as progress:
        runs = simulate_scenarios(scenarios, cfg)
        progress.update(f"writing {out}")
        rec = recording_from_runs(runs, cfg)
        write_output(out, rec, args.block_size)
    truth = write_json(truth_path_for(out), truth_document(cfg, scenarios))
    start, end = rec.span_ns()
    console.print(f"wrote {out} ({len(scenarios)} scenarios, {(end - start) / NS:.1f} s of data) and {truth}")
    return 0


def _simulation_output(args: argparse.Namespace) -> Path:
    from phid_ros.io.outputs import refuse_inputs
    from phid_ros.io.results import truth_path_for

    out = Path(args.out)
    if out.name == "manifest.json":  # a CSV scenario set: its folder is the output
        out.parent.mkdir(parents=True, exist_ok=True)
    refuse_inputs([out, truth_path_for(out)], [])
    for p in (out, truth_path_for(out)):
        if p.exists() and not args.force:
            raise PhidError(f"{p}: already exists, not overwriting (--force to replace it)")
    return out


def _parse_drift(text: str) -> object:
    from phid_ros.sim.ambient import Drift

    try:
        name, rest = text.split("=", 1)
        rel, span = rest.split("@", 1)
        start, end = span.split("-", 1)
        return Drift(name.strip(), float(start), float(end), float(rel))
    except ValueError:
        raise PhidError(f"--drift {text!r}: expected NAME=REL@START-END, e.g. T_d0_prime=0.1@300-1500") from None


def _simulate_ambient(args: argparse.Namespace, console: Console) -> int:
    import numpy as np

    from phid_ros.io.bags import open_message_writer
    from phid_ros.io.recording import Recording, StreamSamples, iter_recording_messages
    from phid_ros.io.results import truth_path_for, write_json
    from phid_ros.io.topics import STREAMS
    from phid_ros.model.conventions import NS
    from phid_ros.sim.ambient import AmbientSettings, ambient_chunks
    from phid_ros.sim.recording import DEFAULT_START_NS, recording_metadata, truth_document
    from phid_ros.sim.runner import SimulationConfig
    from phid_ros.sim.sensors import SensorModel

    out = _simulation_output(args)
    drifts = tuple(_parse_drift(d) for d in (args.drift or []))
    settings = AmbientSettings(duration_s=args.ambient, drifts=drifts, seed=args.seed)  # type: ignore[arg-type]
    cfg = SimulationConfig(f_nominal_hz=args.f_nominal, sensors=SensorModel(seed=args.seed, noiseless=args.noiseless))
    dt_ns = int(round(cfg.dt * NS))
    every = int(round(1 / cfg.dt))
    drifting: dict[str, list[float]] = {d.parameter: [] for d in settings.drifts}
    # simulated and written a chunk at a time (ten minutes of samples in memory, not the day); a
    # chunk is a whole number of messages, so its messages follow the last chunk's in log time
    with ProgressLine(f"simulating {args.ambient:g} s of ambient operation") as progress, atomic_output(out) as tmp:
        writer = open_message_writer(tmp, recording_metadata(cfg))
        try:
            for chunk in ambient_chunks(settings, cfg):
                first = int(round(chunk.t[0] / cfg.dt))
                t_ns = DEFAULT_START_NS + (first + np.arange(len(chunk.t), dtype=np.int64)) * dt_ns
                streams = {
                    s.name: StreamSamples(t_ns.copy(), dt_ns, {c: chunk.measured[c] for c in s.channels})
                    for s in STREAMS
                }
                for item in iter_recording_messages(Recording(streams, []), block_size=args.block_size):
                    writer.write(*item)
                for name, v in chunk.parameters.items():  # once a second, from the run's start
                    drifting[name] += v[(-first) % every :: every].tolist()
                progress.update(f"simulated and written {chunk.t[-1]:.0f} of {args.ambient:g} s")
        except BaseException:
            writer.abort()
            raise
        writer.close()
    truth = truth_document(cfg, [])
    truth["ambient"] = {"duration_s": args.ambient, "seed": args.seed, "drifts": [d.__dict__ for d in drifts]}
    truth["drifting_parameters_every_s"] = drifting
    path = write_json(truth_path_for(out), truth)
    console.print(f"wrote {out} ({args.ambient:g} s, {len(drifts)} drift(s)) and {path}")
    return 0


# -- import-csv ------------------------------------------------------------------
def cmd_import_csv(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.bags import write_recording
    from phid_ros.io.csv_import import import_csv_set

    out = Path(args.out)
    refuse_inputs([out], [args.manifest])
    if out.exists():
        raise PhidError(f"{out}: already exists, not overwriting")
    with ProgressLine(f"importing {args.manifest}") as progress:
        rec, warnings = import_csv_set(args.manifest, strict=args.strict)
        progress.update(f"writing {out}")
        with atomic_output(out) as tmp:
            write_recording(tmp, rec, block_size=args.block_size)
    for w in warnings:
        warn(w)
    console.print(f"wrote {out} ({len(rec.scenarios)} scenarios)")
    return 0


def cmd_import_comtrade(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.comtrade_import import import_comtrade

    return _import_field(args, console, import_comtrade)


def cmd_import_pmu(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.pmu_csv import import_pmu_csv

    return _import_field(args, console, import_pmu_csv)


def _import_field(args: argparse.Namespace, console: Console, read: Callable[..., Recording]) -> int:
    """Field recordings through a channel map -> one scenario set, written as ``phid simulate`` writes."""
    from phid_ros.io.channel_map import load_channel_map

    out = Path(args.out)
    if out.name == "manifest.json":  # a CSV scenario set: its folder is the output
        out.parent.mkdir(parents=True, exist_ok=True)
    refuse_inputs([out], [*args.recordings, *args.map])
    if out.exists():
        raise PhidError(f"{out}: already exists, not overwriting")
    dup = sorted({m for m in args.map if args.map.count(m) > 1})
    if dup:
        raise PhidError(f"--map {dup[0]} given twice")
    maps = [load_channel_map(m) for m in args.map]
    with ProgressLine(f"importing {len(args.recordings)} recording(s)") as progress:
        rec = read(args.recordings, maps)
        progress.update(f"writing {out}")
        write_output(out, rec, args.block_size)
    for w in rec.warnings:  # what the import did: resampled clocks, the field base it calibrated
        warn(w)
    console.print(f"wrote {out} ({len(rec.scenarios)} scenarios)")
    return 0


# -- info --------------------------------------------------------------------------
def _iso(ns: int) -> str:
    return utc_of_stamp(ns).isoformat(timespec="milliseconds")


def cmd_info(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.bags import topic_table, walked_topic_table
    from phid_ros.io.parts import recording_parts
    from phid_ros.io.recording import expected_type

    path = Path(args.bag)
    if path.suffix == ".json":  # a CSV scenario set: no topics, the same streams and scenarios
        from phid_ros.api import load_recording

        rec = load_recording(path)
        for w in rec.warnings:
            warn(w)
        tally = StreamTally()
        tally.add(rec)
        console.print(f"{path} (a CSV scenario set, {len(rec.scenarios)} scenarios)", highlight=False)
        _print_recording(console, tally, rec.scenarios, rec.metadata)
        return 0
    try:
        topics = topic_table(path)
    except PhidError as index_error:
        # a file cut short has no index at its end: walk what is there and say how much it was
        if not path.exists():
            raise
        try:
            topics, cut = walked_topic_table(path)
        except (PhidError, OSError):
            raise index_error from None
        if not cut:
            raise
        if not topics:  # cut before the first whole message: nothing to show
            raise PhidError(cut[0]) from None
        for w in cut:
            warn(w)
    if not any(expected_type(t) for t, _, _ in topics):
        # an output bag (phid replay) or foreign data: the topic table is all there is to show
        table = Table(title=f"{path} (no sensor streams)", title_justify="left")
        for col in ("topic", "type", "messages"):
            table.add_column(col, justify="right" if col == "messages" else "left")
        for topic, msgtype, count in topics:
            table.add_row(topic, msgtype, str(count))
        console.print(table)
        return 0
    # read part by part: a day's bag is summed up in the memory of one part
    tally = StreamTally()
    parts = recording_parts(path)
    scenarios = []
    for part in parts:
        tally.add(part)
        scenarios += part.scenarios
    metadata = parts.metadata  # the reader's own warnings were said above, with the topic table
    table = Table(title=f"{path}", title_justify="left")
    for col in ("topic", "type", "messages"):
        table.add_column(col, justify="right" if col == "messages" else "left")
    for topic, msgtype, count in topics:
        table.add_row(topic, msgtype, str(count))
    console.print(table)
    _print_recording(console, tally, scenarios, metadata)
    if any(not sc.event_ns for sc in scenarios):
        _print_events(console, path, min(s.start_ns for s in tally.summaries()))
    return 0


def _print_events(console: Console, path: Path, t0: int) -> None:
    """The events of test files imported whole (markers without an event stamp), as ``phid
    identify`` cuts them: one per step, return or de-excitation, and what is left out."""
    from phid_ros.api import cut_scenarios

    cut = cut_scenarios(path)
    cols = (Col("scenario", "left", key=True, breakable=True), Col("kind", "left"), Col("event s"), Col("window s"))
    rows = [
        (sc.name, sc.kind, f"{(sc.start_ns - t0) / NS + sc.k_event * sc.dt:.3f}", f"{sc.n * sc.dt:.1f}")
        for sc in cut.scenarios
    ]
    print_table(console, "events (as phid identify cuts the scenarios)", cols, rows)
    for p in cut.problems:
        if "skipped" in p:
            console.print(f"left out: {p}", highlight=False)


def _print_recording(console: Console, tally: StreamTally, scenarios: list, metadata: dict[str, str]) -> None:
    """The streams, the scenarios, what the channels determine and the metadata of a recording."""
    streams = Table(title="sensor streams", title_justify="left")
    for col in ("stream", "samples", "rate Hz", "start (UTC)", "span s", "gaps", "gap s", "backwards"):
        streams.add_column(col, justify="left" if col in ("stream", "start (UTC)") else "right")
    for s in tally.summaries():
        streams.add_row(
            s.name,
            str(s.samples),
            f"{s.rate_hz:g}",
            _iso(s.start_ns),
            f"{(s.end_ns - s.start_ns) / NS:.3f}",
            str(s.gaps),
            f"{s.gap_seconds:.3f}",
            str(s.backwards),
        )
    console.print(streams)
    if scenarios:
        t0 = min(s.start_ns for s in tally.summaries())
        cols = (
            Col("name", "left", key=True, breakable=True),
            Col("kind", "left"),
            Col("role", "left", keep=5),
            Col("damping", "left", keep=4),
            Col("regulator", "left", keep=3),
            Col("event s"),
            Col("window s"),
        )
        rows = [
            (
                sc.name,
                sc.kind,
                sc.role,
                "yes" if sc.generator_damping else "no",
                sc.regulator,
                f"{(sc.event_ns - t0) / NS:.3f}" if sc.event_ns else "?",
                f"{(sc.end_ns - sc.start_ns) / NS:.1f}",
            )
            for sc in scenarios
        ]
        print_table(console, "scenarios", cols, rows)
    _print_determinable(console, tally)
    if metadata:
        console.print("metadata: " + ", ".join(f"{k}={v}" for k, v in sorted(metadata.items())), highlight=False)


def _print_determinable(console: Console, tally: StreamTally) -> None:
    """Channels recorded -> parameters determinable, for a recording that lacks some channels."""
    from phid_ros.cli.tables import print_determinable
    from phid_ros.ident.determinable import plan_for_channels
    from phid_ros.model.channels import CHANNELS

    recorded = tally.measured
    if recorded >= set(CHANNELS):
        return
    planned = plan_for_channels(recorded, {}, no_load=tally.no_load, loaded=tally.loaded)
    missing = ", ".join(c for c in CHANNELS if c not in recorded)
    print_determinable(console, f"what these channels determine (not recorded: {missing})", planned)


# -- identify ------------------------------------------------------------------------
def cmd_identify(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.identify import run

    return run(args, console)


# -- replay --------------------------------------------------------------------------
def cmd_replay(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.replay import run

    return run(args, console)


# -- diagnose ------------------------------------------------------------------------
def cmd_diagnose(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.diagnose import run

    return run(args, console)


# -- track ---------------------------------------------------------------------------
def cmd_track(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.track import run

    return run(args, console)


# -- fleet, history ---------------------------------------------------------------------
def cmd_fleet(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.fleet import run

    return run(args, console)


def cmd_export(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.export import run

    return run(args, console)


def cmd_validate(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.validate import run
    from phid_ros.io.outputs import refuse_inputs

    refuse_inputs([args.json, args.report], [args.dyr, args.input])
    return run(args, console)


def cmd_characterise(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.characterise import characterise_command

    refuse_inputs([args.json], [args.sheet])
    return characterise_command(args, console)


def cmd_history(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.cli.fleet import run_history

    refuse_inputs([args.report], [Path(args.fleet) / "history.sqlite"])
    return run_history(args, console)
