"""``phid replay``: play a recording through the online pipeline, exactly as the nodes run it."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from phid_ros.io.recording import Recording
from phid_ros.io.topics import OUTPUT_TOPICS, output_topic
from phid_ros.model.conventions import NS
from phid_ros.stream.levels import Level, worst
from phid_ros.stream.pipeline import MonitorPipeline, Outputs
from phid_ros.stream.recalibration import RecalibrationOutcome
from phid_ros.stream.record_check import EventVerdict, RecordCheck
from phid_ros.stream.replay import replay

if TYPE_CHECKING:
    from rich.console import Console

    from phid_ros.cli.monitor_report import HealthSnapshot

HEALTH_LOG_MAX = 8000  # diagnostics snapshots kept for the report
BAG_TOPICS = {key: (output_topic(key), msgtype) for key, (_, msgtype) in OUTPUT_TOPICS.items()}


class OutputCollector:
    """Turns pipeline outputs into (log time, topic, type, message) for the output bag."""

    def __init__(
        self,
        pipeline: MonitorPipeline,
        diagnostics_period_ns: int = NS,
        sink: Callable[[int, str, str, object], None] | None = None,
    ) -> None:
        from phid_ros.io.msg_schemas import typestore

        self.types = typestore().types
        self.pipeline = pipeline
        self.sink = sink  # each batch goes out as it is made (to a bag writer); else kept in .messages
        self.messages: list[tuple[int, str, str, object]] = []
        self.counts: dict[str, int] = {}
        self.last_recalibration: RecalibrationOutcome | None = None
        self._diag_period = diagnostics_period_ns
        self._next_diag: int | None = None
        self._batch: list[tuple[int, str, str, object]] = []
        # each stream's health at every diagnostics stamp, for the report: (stamp, {stream: (level, dropped,
        # gaps, clock jumps)})
        self.health_log: list[HealthSnapshot] = []

    def _add(self, key: str, log_ns: int, msg: object) -> None:
        topic, msgtype = BAG_TOPICS[key]
        self._batch.append((int(log_ns), topic, msgtype, msg))
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def __call__(self, out: Outputs) -> None:
        self._collect(out)
        batch, self._batch = sorted(self._batch, key=lambda x: x[0]), []
        if self.sink is None:
            self.messages.extend(batch)
        else:
            for item in batch:
                self.sink(*item)

    def _collect(self, out: Outputs) -> None:
        from phid_ros.stream import messages as m
        from phid_ros.stream.emit import emit

        for r in out.recalibrations:
            self.last_recalibration = r
        for p in emit(self.types, out):
            self._add(p.key, p.log_ns, p.message)
        now = self.pipeline.latest_ns
        if now is not None:
            if self._next_diag is None:
                self._next_diag = now
            while now >= self._next_diag:
                self._log_health(
                    self._next_diag,
                    {
                        n: (self.pipeline.status(n)[0], h.dropped, h.gaps - h.pauses, h.clock_jumps)
                        for n, h in self.pipeline.health.items()
                    },
                )
                self._add(
                    "diagnostics",
                    self._next_diag,
                    m.diagnostics_message(
                        self.types,
                        self._next_diag,
                        self.pipeline.health,
                        self.last_recalibration,
                        stream_now_ns=self.pipeline.aligner.stream_now_ns,
                        stale_ns=self.pipeline.aligner.stale_ns,
                        unit=self.pipeline.settings.unit,
                        record=self.pipeline.record_check,
                    ),
                )
                self._next_diag += self._diag_period

    def _log_health(self, t_ns: int, snapshot: dict[str, tuple[Level, int, int, int]]) -> None:
        """One snapshot a diagnostics period; past HEALTH_LOG_MAX of them, neighbours are merged in
        pairs (the worse level, the later counters: they are running totals), so a day's replay
        keeps as many as an hour's (86 400 snapshots held 90 MB) and a short ERROR is not lost."""
        self.health_log.append((t_ns, snapshot))
        if len(self.health_log) <= HEALTH_LOG_MAX:
            return
        merged = []
        for (t0, a), (_, b) in zip(self.health_log[0::2], self.health_log[1::2]):
            worse = {n: (worst(a[n][0], b[n][0]), *b[n][1:]) if n in a else b[n] for n in b}
            merged.append((t0, worse))
        if len(self.health_log) % 2:
            merged.append(self.health_log[-1])
        self.health_log = merged

    def sorted(self) -> list[tuple[int, str, str, object]]:
        return sorted(self.messages, key=lambda x: x[0])


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
    from phid_ros.cli.tables import CONCISE_LEGEND, Col, estimate_text, fmt, print_table
    from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME, SYMBOLS
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
        print_table(
            console,
            f"parameters in force at the end (recalibration at {(last.stream_time_ns - start) / NS:.1f} s)",
            [Col("param", "left"), Col("unit", "left"), Col("value(std)")],
            prows,
            CONCISE_LEGEND,
        )
    elif partial := next((r for r in reversed(outputs.recalibrations) if r.determined), None):
        est = partial.determined
        held = partial.result.constraints.fixed if partial.result else {}

        def shown(n: str) -> str:
            if n in est:
                return estimate_text(est[n].value, est[n].std, True)
            return f"{held[n]:g} held" if n in held else "withheld"

        prows = [[SYMBOLS[n], SPECS_BY_NAME[n].unit, shown(n)] for n in PARAMETER_NAMES]
        print_table(
            console,
            f"no full set in force at the end; the partial set published at "
            f"{(partial.stream_time_ns - start) / NS:.1f} s",
            [Col("param", "left"), Col("unit", "left"), Col("value(std)")],
            prows,
            CONCISE_LEGEND,
        )
    elif pipeline.parameters is None:
        why = (
            f"{len(outputs.recalibrations)} recalibration(s), none with a complete set: their reasons above"
            if outputs.recalibrations
            else "not enough events for a recalibration"
        )
        console.print(f"parameters in force at the end: none ({why})", highlight=False)
    if fitted := next((r for r in reversed(outputs.recalibrations) if r.controls), None):
        from phid_ros.cli.identify import print_controls

        console.print(f"fitted beside the machine at {(fitted.stream_time_ns - start) / NS:.1f} s:", highlight=False)
        print_controls(console, fitted.controls)
    if pipeline.recalibrator.last_good is not None and outputs.energy:
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
    import itertools
    import resource

    from phid_ros.cli.common import warn
    from phid_ros.cli.progress import ProgressLine
    from phid_ros.ident.constraints import parse_constraints
    from phid_ros.ident.pipeline import IdentifyOptions
    from phid_ros.io.bags.recordings import open_message_writer
    from phid_ros.io.files.outputs import atomic_output, partial_path, refuse_inputs
    from phid_ros.io.overview import Overview
    from phid_ros.io.parts import recording_parts
    from phid_ros.io.recording import not_recorded
    from phid_ros.stream.pipeline import PipelineSettings

    out_path = Path(args.out)
    refuse_inputs([out_path, args.store, args.report], [args.bag])
    refuse_inputs([out_path], [args.store])
    if args.record:
        refuse_inputs([out_path, args.store, args.report], [args.record])
    check_output(out_path, args.force)
    # the recording is read part by part as it is played: memory holds one part, not the file
    constraints = parse_constraints(args.fix, saturation=args.saturation)  # a typo said before the reading
    with ProgressLine(f"reading {args.bag}"):
        parts = recording_parts(args.bag)
        part_iter = iter(parts)
        first = next(part_iter)
    unit = args.unit or parts.metadata.get("unit", "")
    # the grid at the PT/CT rate, as phid identify aligns the recording (a node: its sample_rate_hz)
    settings = PipelineSettings(
        period_ns=first.streams["pt_ct"].period_ns if "pt_ct" in first.streams else PipelineSettings.period_ns,
        store_path=args.store or ":memory:",
        unit=unit,
        not_recorded=not_recorded(parts.metadata),
        identify=IdentifyOptions(baseline=False, constraints=constraints),
    )
    pipeline = MonitorPipeline(settings)
    if args.record:  # read before the replay: a record it cannot read is said now, not at the first event
        from phid_ros.api import record_check

        pipeline.record_check = record_check(args.record)
    if len(pipeline.store):
        # a kept store is the deployment's memory: its events take part in every recalibration, so
        # a replay into it differs from one into an empty store, and says so
        console.print(
            f"store {args.store}: {len(pipeline.store)} events from earlier runs take part in the recalibrations "
            "(an empty store, or none, gives the same result on every run)",
            highlight=False,
            markup=False,
        )
    overview = Overview()
    start_ns = min((int(s.t_ns[0]) for s in first.streams.values() if len(s)), default=0)

    def read_on() -> Iterator[Recording]:
        for part in itertools.chain([first], part_iter):
            overview.add(part)
            yield part

    t0 = time.perf_counter()
    # outputs go to OUT.partial as they are made and become OUT at the end: an interruption
    # leaves what was published so far, readable, and the events already in the store
    with atomic_output(out_path, keep_partial=True) as tmp:
        writer = open_message_writer(tmp, {"source": f"phid replay {args.bag}"}, background=True)
        collector = OutputCollector(pipeline, sink=writer.write)
        events = 0

        def collect(out: Outputs) -> None:
            nonlocal events
            collector(out)
            events += len(out.events)

        played_s = 0.0

        def doing() -> str:
            # the file is read ahead of the play (all of a short one at once): its share is said
            # while it grows, then what the pipeline's recalibration is busy with, which is where
            # a commissioning day's minutes go (its exciter search), not "100 % of the file (still)"
            share = round(100 * parts.fraction)
            read = f", {share} % of the file read" if share < 100 else ""
            line = f"replaying: {played_s:.0f} s of stream time{read}, {events} event(s)"
            busy = pipeline.recalibrator.activity
            return f"{line}; {busy}" if busy else line

        def played(seconds: float) -> None:
            nonlocal played_s
            played_s = seconds
            # on a terminal the line is redrawn; in a log it is written every few seconds of wall time
            progress.update(doing())

        try:
            with ProgressLine(f"replaying {args.bag}", source=doing) as progress:
                outputs = replay(
                    read_on(),
                    pipeline,
                    rate=args.rate,
                    on_outputs=collect,
                    keep_arrays=False,
                    progress=played,
                )
        except BaseException:
            writer.close()
            pipeline.close()
            warn(f"replay stopped: what was published so far is in {partial_path(out_path)}")
            raise
        writer.close()
    for w in parts.warnings:
        warn(w)
    wall = time.perf_counter() - t0
    start, end = overview.span_ns()
    span = (end - start) / NS
    print_summary(console, start_ns, pipeline, outputs, collector)
    if args.report:
        from phid_ros.cli.monitor_report import write_replay_report

        with ProgressLine(f"writing {args.report}"):
            write_replay_report(args.report, overview, outputs, collector.health_log, source=str(args.bag))
        console.print(f"wrote {args.report}", highlight=False)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    # the one line that differs between two replays of the same bag: it is measured, not replayed
    console.print(
        f"wrote {sum(collector.counts.values())} messages to {out_path}; "
        f"timing: {span:.1f} s replayed in {wall:.2f} s wall time ({span / wall:.0f}x real time), "
        f"{pipeline.samples_in / wall / 1e6:.2f} M channel-samples/s, peak memory {peak:.0f} MB",
        highlight=False,
    )
    pipeline.close()
    return 0
