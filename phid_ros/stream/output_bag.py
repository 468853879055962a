"""A replay's outputs as the nodes publish them: (log time, topic, type, message) for an output
bag, and each stream's health at every diagnostics stamp for the report. ``phid replay`` and
``phid_ros.api.replay_to_bag`` write through it; the nodes publish the same messages."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from phid_ros.io.topics import OUTPUT_TOPICS, output_topic
from phid_ros.model.conventions import NS
from phid_ros.stream.levels import Level, worst
from phid_ros.stream.pipeline import MonitorPipeline, Outputs
from phid_ros.stream.recalibration import RecalibrationOutcome
from phid_ros.stream.tracker import TrackPoint

# (stamp ns, {stream: (level, dropped, gaps, clock jumps)}): one diagnostics stamp of a replay
HealthSnapshot = tuple[int, dict[str, tuple[Level, int, int, int]]]

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


def write_tracked(points: Sequence[TrackPoint], out: str | Path) -> int:
    """The tracker's hops as ``tracked_parameters`` messages in a bag (written whole: an
    interruption leaves no half-written file); the count written."""
    from phid_ros.io.bags.recordings import write_messages
    from phid_ros.io.files.outputs import atomic_output
    from phid_ros.io.msg_schemas import typestore
    from phid_ros.stream.messages import tracked_message

    types = typestore().types
    topic, msgtype = BAG_TOPICS["tracked_parameters"]
    msgs = [(p.t_ns, topic, msgtype, tracked_message(types, p)) for p in points]
    with atomic_output(out) as tmp:
        write_messages(tmp, msgs)
    return len(msgs)
