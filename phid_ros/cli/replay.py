"""``phid replay``: play a recording through the online pipeline, exactly as the nodes run it."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from phid_ros.io.recording import DEFAULT_BLOCK_SIZE, NS, Recording, block_bounds
from phid_ros.io.topics import STREAMS_BY_NAME
from phid_ros.stream.pipeline import Marker, MonitorPipeline, Outputs

PROCESS_EVERY_NS = NS // 2  # stream time between pipeline runs while feeding
MAX_PACE_STEP_NS = 60 * NS  # a stamp step beyond this is a clock jump, not time to wait for


def markers_of(rec: Recording) -> list[Marker]:
    return [Marker(s.name, s.kind, s.role, s.generator_damping, s.start_ns, s.end_ns) for s in rec.scenarios]


def sensor_blocks(rec: Recording, block_size: int = DEFAULT_BLOCK_SIZE) -> list[tuple[int, str, int, int]]:
    """(stamp of the block's last sample, stream, start, stop), in the order a recorder logged them.

    A bag remembers where each message stood in the file: its messages are fed in that
    order, as a subscriber received them, so a clock that jumps (back, or ahead) reaches
    the aligner as a jump and a wild stamp as one wild block. Recordings without that
    order (CSV imports, simulations) have monotonic stamps; their blocks go by stamp.
    """
    recorded = all(s.msg_seq is not None and s.msg_offsets is not None for s in rec.streams.values())
    keyed: list[tuple[int, int, str, int, int]] = []
    for name, s in rec.streams.items():
        if recorded:
            starts = s.msg_offsets.tolist()  # type: ignore[union-attr]
            stops = starts[1:] + [len(s)]
            for seq, a, b in zip(s.msg_seq.tolist(), starts, stops):  # type: ignore[union-attr]
                if b > a:
                    keyed.append((seq, int(s.t_ns[b - 1]), name, a, b))
        else:
            for a, b in block_bounds(s.t_ns, s.period_ns, block_size):
                keyed.append((int(s.t_ns[b - 1]), int(s.t_ns[b - 1]), name, a, b))
    keyed.sort(key=lambda x: x[0])
    return [(end, name, a, b) for _, end, name, a, b in keyed]


def replay(
    rec: Recording,
    pipeline: MonitorPipeline,
    *,
    rate: float | None = None,
    block_size: int = DEFAULT_BLOCK_SIZE,
    on_outputs: Callable[[Outputs], None] | None = None,
    keep_arrays: bool = True,
) -> Outputs:
    """Feed every sensor block in stamp order; ``rate`` paces it at R x real time (None: as fast as possible).

    ``on_outputs`` sees every output in full; the returned summary drops the bulk arrays
    when ``keep_arrays`` is False, so a long replay's memory stays flat.
    """
    for m in markers_of(rec):
        pipeline.add_marker(m)
    total = Outputs()
    blocks = sensor_blocks(rec, block_size)
    if not blocks:
        return total
    wall0 = time.perf_counter()
    played = 0  # stream time played so far: stamps advance it, a clock that jumps does not
    prev_end = blocks[0][0]
    next_process = PROCESS_EVERY_NS
    for end_ns, name, a, b in blocks:
        s = rec.streams[name]
        spec = STREAMS_BY_NAME[name]
        if 0 < end_ns - prev_end <= MAX_PACE_STEP_NS:
            played += end_ns - prev_end
        if end_ns > prev_end or end_ns < prev_end - MAX_PACE_STEP_NS:
            prev_end = end_ns
        if rate:
            ahead = played / NS / rate - (time.perf_counter() - wall0)
            if ahead > 0:
                time.sleep(ahead)
        pipeline.ingest_message(name, int(s.t_ns[a]), s.period_ns, {c: s.channels[c][a:b] for c in spec.channels})
        if played >= next_process:
            out = pipeline.process()
            next_process = played + PROCESS_EVERY_NS
            total.extend(out if keep_arrays else out.light())
            if on_outputs:
                on_outputs(out)
    out = pipeline.process(final=True)
    total.extend(out if keep_arrays else out.light())
    if on_outputs:
        on_outputs(out)
    return total


def event_times(outputs: Outputs) -> np.ndarray:
    return np.array([e.inception_ns for e in outputs.events], dtype=np.int64)


# -- the command -----------------------------------------------------------------------------
OUTPUT_TOPICS = {
    "events": ("/phid/events", "phid_msgs/msg/DisturbanceEvent"),
    "windows": ("/phid/event_windows", "phid_msgs/msg/EventWindow"),
    "parameters": ("/phid/parameters", "phid_msgs/msg/GeneratorParameters"),
    "hamiltonian": ("/phid/hamiltonian", "phid_msgs/msg/HamiltonianState"),
    "diagnostics": ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
}


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
        self.last_status: str | None = None
        self._diag_period = diagnostics_period_ns
        self._next_diag: int | None = None
        self._batch: list[tuple[int, str, str, object]] = []

    def _add(self, key: str, log_ns: int, msg: object) -> None:
        topic, msgtype = OUTPUT_TOPICS[key]
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

        for e in out.events:
            self._add("events", e.inception_ns, m.event_message(self.types, e))
        for w in out.windows:
            self._add(
                "windows", int(w.t_ns[-1]) if len(w.t_ns) else w.event.inception_ns, m.window_message(self.types, w)
            )
        for r in out.recalibrations:
            self.last_status = r.status
            msg = m.parameters_message(self.types, r)
            if msg is not None:
                self._add("parameters", r.stream_time_ns, msg)
        for e in out.energy:
            for t, msg in zip(e.t_ns, m.hamiltonian_messages(self.types, e)):
                self._add("hamiltonian", int(t), msg)
        now = self.pipeline.latest_ns
        if now is not None:
            if self._next_diag is None:
                self._next_diag = now
            while now >= self._next_diag:
                self._add(
                    "diagnostics",
                    self._next_diag,
                    m.diagnostics_message(
                        self.types,
                        self._next_diag,
                        self.pipeline.health,
                        self.last_status,
                        stream_now_ns=self.pipeline.aligner.stream_now_ns,
                        stale_ns=self.pipeline.aligner.stale_ns,
                    ),
                )
                self._next_diag += self._diag_period

    def sorted(self) -> list[tuple[int, str, str, object]]:
        return sorted(self.messages, key=lambda x: x[0])


def check_output(out: Path, force: bool) -> None:
    """An existing output is replaced only with --force or when an earlier phid replay wrote it."""
    from phid_ros.errors import PhidError
    from phid_ros.io.bags import recording_source

    if out.exists() and not force and not (recording_source(out) or "").startswith("phid replay"):
        raise PhidError(f"{out}: already exists and was not written by phid replay; not overwriting (--force to)")


def run(args: object, console: object) -> int:
    import resource

    from rich.markup import escape
    from rich.table import Table

    from phid_ros.cli.common import read_input, warn
    from phid_ros.io.bags import open_message_writer
    from phid_ros.io.outputs import atomic_output, partial_path, refuse_inputs
    from phid_ros.model.parameters import PARAMETER_NAMES
    from phid_ros.stream.pipeline import PipelineSettings

    out_path = Path(args.out)  # type: ignore[attr-defined]
    refuse_inputs([out_path, args.store], [args.bag])  # type: ignore[attr-defined]
    refuse_inputs([out_path], [args.store])  # type: ignore[attr-defined]
    check_output(out_path, args.force)  # type: ignore[attr-defined]
    rec, _ = read_input(args.bag)  # type: ignore[attr-defined]
    unit = args.unit or rec.metadata.get("unit", "")  # type: ignore[attr-defined]
    settings = PipelineSettings(store_path=args.store or ":memory:", unit=unit)  # type: ignore[attr-defined]
    pipeline = MonitorPipeline(settings)
    t0 = time.perf_counter()
    # outputs go to OUT.partial as they are made and become OUT at the end: an interruption
    # leaves what was published so far, readable, and the events already in the store
    with atomic_output(out_path, keep_partial=True) as tmp:
        writer = open_message_writer(tmp, {"source": f"phid replay {args.bag}"})  # type: ignore[attr-defined]
        collector = OutputCollector(pipeline, sink=writer.write)  # type: ignore[attr-defined]
        try:
            outputs = replay(rec, pipeline, rate=args.rate, on_outputs=collector, keep_arrays=False)  # type: ignore[attr-defined]
        except BaseException:
            writer.close()  # type: ignore[attr-defined]
            pipeline.close()
            warn(f"replay stopped: what was published so far is in {partial_path(out_path)}")
            raise
        writer.close()  # type: ignore[attr-defined]
    wall = time.perf_counter() - t0
    start, end = rec.span_ns()
    span = (end - start) / NS
    c = console
    ev = Table(title=f"events found ({len(outputs.events)})", title_justify="left")
    for col in ("id", "kind", "scenario", "t s", "clearing s", "severity", "window"):
        ev.add_column(col)
    usable = {w.event.event_id: ("ok" if w.usable else w.reason) for w in outputs.windows}
    for e in outputs.events:
        ev.add_row(
            escape(e.event_id),
            e.kind,
            escape(e.name or "—"),
            f"{(e.inception_ns - start) / NS:.3f}",
            f"{(e.clearing_ns - start) / NS:.3f}" if e.clearing_ns else "",
            f"{e.severity:+.3f}",
            escape(usable.get(e.event_id, "pending")),
        )
    c.print(ev)  # type: ignore[attr-defined]
    for r in outputs.recalibrations:
        c.print(
            f"recalibration at {(r.stream_time_ns - start) / NS:.1f} s with {len(r.event_ids)} events: "  # type: ignore[attr-defined]
            f"{'accepted' if r.accepted else 'rejected'} — {escape(r.status)} ({r.seconds:.2f} s)",
            highlight=False,
        )
    p = pipeline.parameters
    if p is not None:
        c.print(
            "final parameters: " + ", ".join(f"{n} = {getattr(p, n):.5g}" for n in PARAMETER_NAMES),  # type: ignore[attr-defined]
            highlight=False,
        )
    else:
        c.print("final parameters: none (not enough events for a recalibration)")  # type: ignore[attr-defined]
    if pipeline.recalibrator.last_good is not None and outputs.energy:
        last = outputs.energy[-1]
        # the running summary keeps one sample per batch: count what was published instead
        n_energy = collector.counts.get(OUTPUT_TOPICS["hamiltonian"][0], 0)
        c.print(
            f"Hamiltonian at the end: {last.value[-1]:.5f} (kinetic {last.kinetic[-1]:.2e}, "  # type: ignore[attr-defined]
            f"magnetic d {last.magnetic_d[-1]:.4f}, q {last.magnetic_q[-1]:.4f}); "
            f"{n_energy} samples published at {settings.hamiltonian_rate_hz:g} Hz",
            highlight=False,
        )
    health = Table(title="stream health", title_justify="left")
    for col in ("stream", "level", "status", "samples", "dropped", "gaps", "clock jumps"):
        health.add_column(col)
    for name, h in pipeline.health.items():
        level, msg = pipeline.aligner.status(name)
        health.add_row(name, level, msg, str(h.samples), str(h.dropped), str(h.gaps), str(h.clock_jumps))
    c.print(health)  # type: ignore[attr-defined]
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    c.print(
        f"replayed {span:.1f} s in {wall:.2f} s ({span / wall:.0f}x real time), "  # type: ignore[attr-defined]
        f"{pipeline.samples_in / wall / 1e6:.2f} M channel-samples/s, peak memory {peak:.0f} MB; "
        f"wrote {sum(collector.counts.values())} messages to {out_path}",
        highlight=False,
    )
    pipeline.close()
    return 0
