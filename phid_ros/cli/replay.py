"""``phid replay``: play a recording through the online pipeline, exactly as the nodes run it."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from phid_ros.model.conventions import NS
from phid_ros.stream.output_bag import BAG_TOPICS, OutputCollector
from phid_ros.stream.pipeline import MonitorPipeline, Outputs
from phid_ros.stream.recalibration import RecalibrationOutcome
from phid_ros.stream.record_check import EventVerdict, RecordCheck

if TYPE_CHECKING:
    from rich.console import Console


def check_output(out: Path, force: bool) -> None:
    """An existing output is replaced only with --force or when an earlier phid replay wrote it."""
    from phid_ros.errors import PhidError
    from phid_ros.io.bags.recordings import recording_source

    if out.exists() and not force and not (recording_source(out) or "").startswith("phid replay"):
        raise PhidError(
            f"{out}: already exists and was not written by phid replay; not overwriting (--force to replace it)"
        )


def recalibration_text(r: RecalibrationOutcome, start: int) -> str:
    """One recalibration, as the terminal says it (``RecalibrationOutcome.said``)."""
    outcome, why = r.said()
    head = f"recalibration at {(r.stream_time_ns - start) / NS:.1f} s with {len(r.event_ids)} event(s): {outcome}"
    if not why:
        return head
    return f"{head}: {why}" if outcome.startswith("no set") else f"{head} ({why})"


def print_summary(
    console: Console, start: int, pipeline: MonitorPipeline, outputs: Outputs, collector: OutputCollector
) -> None:
    """What a replay found, in the same words on every run of the same bag (no wall times);
    ``start``: the recording's first stamp, times are shown from it."""
    _print_events(console, start, pipeline, outputs)
    _print_parameters(console, start, pipeline, outputs)
    if fitted := next((r for r in reversed(outputs.recalibrations) if r.controls), None):
        from phid_ros.cli.identify import print_controls

        console.print(f"fitted beside the machine at {(fitted.stream_time_ns - start) / NS:.1f} s:", highlight=False)
        print_controls(console, fitted.controls)
    if pipeline.recalibrator.last_good is not None and outputs.energy:
        from phid_ros.cli.tables import fmt

        e = outputs.energy[-1]
        n_energy = collector.counts.get(BAG_TOPICS["hamiltonian"][0], 0)
        console.print(
            f"Hamiltonian at the end: {e.value[-1]:.5f} pu·s (MJ per MVA of rating): kinetic {fmt(e.kinetic[-1], 3)}, "
            f"magnetic d {e.magnetic_d[-1]:.4f}, q {e.magnetic_q[-1]:.4f} pu·s; "
            f"{n_energy} samples published at {pipeline.settings.hamiltonian_rate_hz:g} Hz",
            highlight=False,
        )
    if pipeline.record_check is not None:
        print_record_verdicts(console, start, pipeline.record_check, pipeline.record_check.verdicts)
    _print_health(console, pipeline)


def _print_events(console: Console, start: int, pipeline: MonitorPipeline, outputs: Outputs) -> None:
    """The events found, the measurements lost and each recalibration."""
    from phid_ros.cli.tables import Col, print_table
    from phid_ros.stream.detector import lost_measurement_text, severity_text, window_status

    usable = {w.event.event_id: window_status(w) for w in outputs.windows}
    settled = {w.event.event_id: w.settled for w in outputs.windows}
    cols = [
        Col("t s"),
        Col("kind", "left"),
        Col("scenario", "left", keep=5, text=True, breakable=True),
        Col("clearing s", keep=3),
        Col("severity", "left", text=True),
        Col("window", "left", text=True),
    ]
    rows = [
        [
            f"{(e.inception_ns - start) / NS:.3f}",
            e.kind,
            e.name or "—",
            f"{(e.clearing_ns - start) / NS:.3f}" if e.clearing_ns else "",
            severity_text(e.kind, e.severity, settled.get(e.event_id)),
            usable.get(e.event_id, "pending"),
        ]
        for e in outputs.events
    ]
    print_table(console, f"events found ({len(outputs.events)}); t from the start of the recording", cols, rows)
    for lost, back in pipeline.detector.lost_measurements:
        console.print(lost_measurement_text(lost, back, start, ended=True), highlight=False)
    for r in outputs.recalibrations:
        console.print(recalibration_text(r, start), highlight=False, markup=False)


def _print_parameters(console: Console, start: int, pipeline: MonitorPipeline, outputs: Outputs) -> None:
    """The parameters in force at the end: the last full set, else the last partial one, else why none."""
    from phid_ros.cli.tables import CONCISE_LEGEND, Col, estimate_text, print_table
    from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME, SYMBOLS

    cols = [Col("param", "left"), Col("unit", "left"), Col("value(std)")]
    last = next((r for r in reversed(outputs.recalibrations) if r.accepted and r.result is not None), None)
    if last is not None and last.result is not None:
        est = last.result.estimates
        prows = [
            [
                SYMBOLS[n],
                SPECS_BY_NAME[n].unit,
                estimate_text(est[n].value, est[n].std, est[n].identifiable) if n in est else "—",
            ]
            for n in PARAMETER_NAMES
        ]
        title = f"parameters in force at the end (recalibration at {(last.stream_time_ns - start) / NS:.1f} s)"
        print_table(console, title, cols, prows, CONCISE_LEGEND)
    elif partial := next((r for r in reversed(outputs.recalibrations) if r.determined), None):
        est = partial.determined
        held = partial.result.constraints.fixed if partial.result else {}

        def shown(n: str) -> str:
            if n in est:
                return estimate_text(est[n].value, est[n].std, True)
            return f"{held[n]:g} held" if n in held else "withheld"

        prows = [[SYMBOLS[n], SPECS_BY_NAME[n].unit, shown(n)] for n in PARAMETER_NAMES]
        title = (
            f"no full set in force at the end; the partial set published at "
            f"{(partial.stream_time_ns - start) / NS:.1f} s"
        )
        print_table(console, title, cols, prows, CONCISE_LEGEND)
    elif pipeline.parameters is None:
        why = (
            f"{len(outputs.recalibrations)} recalibration(s), none with a complete set: their reasons above"
            if outputs.recalibrations
            else "not enough events for a recalibration"
        )
        console.print(f"parameters in force at the end: none ({why})", highlight=False)


def _print_health(console: Console, pipeline: MonitorPipeline) -> None:
    from phid_ros.cli.tables import Col, print_table

    hrows = []
    for name, h in pipeline.health.items():
        level, msg = pipeline.status(name)
        counts = (h.samples, h.dropped, h.gaps - h.pauses, h.clock_jumps)
        hrows.append([name, str(level), msg, *map(str, counts)])
    hcols = [Col("stream", "left"), Col("level", "left"), Col("status", "left", text=True), Col("samples")]
    hcols += [Col("dropped"), Col("gaps (lost)"), Col("clock jumps")]
    print_table(console, "stream health", hcols, hrows)


def print_record_verdicts(console: Console, start: int, record: RecordCheck, verdicts: list[EventVerdict]) -> None:
    """Each event played into the record on file: its checks' worst, the verdict; then the record's state."""
    from phid_ros.cli.tables import Col, print_table
    from phid_ros.controls.unit_validation import CHANNELS

    rows = []
    for v in verdicts:
        top = v.worst()
        failed = ", ".join(CHANNELS[c.channel][1] for c in v.failed())
        rows.append(
            [
                f"{(v.stream_time_ns - start) / NS:.1f}",
                v.event_id,
                v.kind,
                str(len(v.checks)),
                f"{CHANNELS[top.channel][1]} {top.max_error:.4f} / {top.band:.4f}" if top else "",
                "pass" if v.passed else f"FAIL ({failed})",
            ]
        )
    cols = [Col("end s"), Col("event", "left", breakable=True), Col("kind", "left", keep=3), Col("checks", keep=2)]
    cols += [Col("worst: |error| / band pu", "left"), Col("verdict", "left", text=True)]
    print_table(console, f"the record on file against each event: {record.describe}", cols, rows)
    level, message = record.status()
    console.print(f"record on file: {level}: {message}", highlight=False, markup=False)


def replay_command(args: Any, console: Any) -> int:
    import resource

    from phid_ros.api import ReplayProgress, replay_to_bag
    from phid_ros.cli.common import warn
    from phid_ros.cli.progress import ProgressLine
    from phid_ros.ident.constraints import parse_constraints
    from phid_ros.io.files.outputs import partial_path

    out_path = Path(args.out)
    _refuse_outputs(args, out_path)
    constraints = parse_constraints(args.fix, saturation=args.saturation)  # a typo said before the reading
    now = ReplayProgress(0.0, 0.0, 0, "")
    live: list[MonitorPipeline] = []  # the pipeline, once made: what its recalibration does, read as it goes

    def started(pipeline: MonitorPipeline) -> None:
        live.append(pipeline)
        # a recalibration's steps shown when they begin, not at the next poll
        pipeline.recalibrator.on_activity = lambda: progress.update(doing())
        if len(pipeline.store):
            # a kept store is the deployment's memory: its events take part in every recalibration,
            # so a replay into it differs from one into an empty store, and says so
            console.print(
                f"store {args.store}: {len(pipeline.store)} events from earlier runs take part in the "
                "recalibrations (an empty store, or none, gives the same result on every run)",
                highlight=False,
                markup=False,
            )

    def doing() -> str:
        # the file is read ahead of the play (all of a short one at once): its share is said while
        # it grows, then what the pipeline's recalibration is busy with, which is where a
        # commissioning day's minutes go (its exciter search), not "100 % of the file (still)"
        share = round(100 * now.read_share)
        read = f", {share} % of the file read" if share < 100 else ""
        line = f"replaying: {now.played_s:.0f} s of stream time{read}, {now.events} event(s)"
        busy = live[0].recalibrator.activity if live else now.busy
        return f"{line}; {busy}" if busy else line

    try:
        with ProgressLine(f"replaying {args.bag}", source=doing) as progress:

            def played(p: ReplayProgress) -> None:
                nonlocal now
                now = p
                # on a terminal the line is redrawn; in a log it is written every few seconds of wall time
                progress.update(doing())

            run = replay_to_bag(
                args.bag,
                out_path,
                record=args.record,
                store=args.store,
                unit=args.unit or "",
                constraints=constraints,
                rate=args.rate,
                progress=played,
                started=started,
            )
    except BaseException:
        if partial_path(out_path).exists():
            warn(f"replay stopped: what was published so far is in {partial_path(out_path)}")
        raise
    for w in run.warnings:
        warn(w)
    start, end = run.overview.span_ns()
    span = (end - start) / NS
    print_summary(console, run.start_ns, run.pipeline, run.outputs, run.collector)
    if args.report:
        _write_report(args, console, run)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    # the one line that differs between two replays of the same bag: it is measured, not replayed
    console.print(
        f"wrote {sum(run.collector.counts.values())} messages to {out_path}; "
        f"timing: {span:.1f} s replayed in {run.wall_s:.2f} s wall time ({span / run.wall_s:.0f}x real time), "
        f"{run.pipeline.samples_in / run.wall_s / 1e6:.2f} M channel-samples/s, peak memory {peak:.0f} MB",
        highlight=False,
    )
    return 0


def _write_report(args: Any, console: Any, run: Any) -> None:
    from phid_ros.cli.monitor_report import write_replay_report
    from phid_ros.cli.progress import ProgressLine

    with ProgressLine(f"writing {args.report}"):
        write_replay_report(args.report, run.overview, run.outputs, run.collector.health_log, source=str(args.bag))
    console.print(f"wrote {args.report}", highlight=False)


def _refuse_outputs(args: Any, out_path: Path) -> None:
    """No output may be an input, the store not the output bag, and the output bag not another
    program's file."""
    from phid_ros.io.files.outputs import refuse_inputs

    refuse_inputs([out_path, args.store, args.report], [args.bag])
    refuse_inputs([out_path], [args.store])
    if args.record:
        refuse_inputs([out_path, args.store, args.report], [args.record])
    check_output(out_path, args.force)
