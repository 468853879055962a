"""A recording played through the online pipeline exactly as the nodes receive it.

The one driver from a recorded (or simulated) recording to the pipeline's entry point: the
blocks go in as the sensor messages that carried them, in the order a recorder logged them.
``phid replay`` publishes what comes out; ``phid identify`` and ``phid diagnose`` take the event
windows of a recording without scenario markers from here (:func:`event_windows`), so the
windows a node would cut are the windows the batch commands use.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterable

import numpy as np

from phid_ros.ident.scenario import DEFAULT_THRESHOLDS, StepThresholds
from phid_ros.io.recording import DEFAULT_BLOCK_SIZE, Recording, block_bounds
from phid_ros.io.topics import ALL_STREAMS_BY_NAME
from phid_ros.model.conventions import NS
from phid_ros.model.parameters import GeneratorParameters
from phid_ros.stream.align import Run, StreamHealth
from phid_ros.stream.detector import DetectorSettings, EventWindow
from phid_ros.stream.pipeline import MonitorPipeline, Outputs, PipelineSettings
from phid_ros.stream.tracker import TrackerSettings, TrackPoint

PROCESS_EVERY_NS = NS // 2  # stream time between pipeline runs while feeding
MAX_PACE_STEP_NS = 60 * NS  # a stamp step beyond this is a clock jump, not time to wait for


def stream_blocks(rec: Recording, block_size: int = DEFAULT_BLOCK_SIZE) -> list[tuple[int, str, int, int]]:
    """(stamp of the block's last sample, stream, start, stop), in the order a recorder logged them.

    A bag remembers where each message stood in the file: its messages are fed in that
    order, as a subscriber received them, so a clock that jumps (back, or ahead) reaches
    the aligner as a jump and a wild stamp as one wild block. Recordings without that
    order (CSV imports, simulations) have monotonic stamps; their blocks go by stamp.
    """
    # a recorder's own streams too: the pipeline keeps them beside the grid for the event windows
    sensors = rec.streams
    recorded = all(s.msg_seq is not None and s.msg_offsets is not None for s in sensors.values())
    keys, ends, names, starts, stops = [], [], [], [], []
    for i, (name, s) in enumerate(sensors.items()):
        if recorded:
            a = np.asarray(s.msg_offsets, dtype=np.int64)
            b = np.append(a[1:], len(s))
            keep = b > a
            a, b = a[keep], b[keep]
            key = np.asarray(s.msg_seq, dtype=np.int64)[keep]
        else:
            bounds = np.array(block_bounds(s.t_ns, s.period_ns, block_size), dtype=np.int64).reshape(-1, 2)
            a, b = bounds[:, 0], bounds[:, 1]
        end = s.t_ns[b - 1] if len(b) else np.zeros(0, np.int64)
        keys.append(key if recorded else end)
        ends.append(end)
        names.append(np.full(len(a), i))
        starts.append(a)
        stops.append(b)
    if not keys:
        return []
    # stable: messages of equal key keep the streams' order, then their own (as a sort by key would)
    order = np.argsort(np.concatenate(keys), kind="stable")
    stream_names = list(sensors)
    return [
        (end, stream_names[i], a, b)
        for end, i, a, b in zip(*(np.concatenate(x)[order].tolist() for x in (ends, names, starts, stops)), strict=True)
    ]


def replay(
    rec: Recording | Iterable[Recording],
    pipeline: MonitorPipeline,
    *,
    rate: float | None = None,
    block_size: int = DEFAULT_BLOCK_SIZE,
    on_outputs: Callable[[Outputs], None] | None = None,
    keep_arrays: bool = True,
    progress: Callable[[float], None] | None = None,
) -> Outputs:
    """Feed every sensor block in stamp order; ``rate`` paces it at R x real time (None: as fast as possible).

    ``rec`` is a recording or its consecutive parts (:mod:`phid_ros.io.parts`): the pipeline is
    fed and run at the same points either way, so the outputs are the same, and only one part is
    held at a time. ``on_outputs`` sees every output in full; the returned summary drops the bulk
    arrays when ``keep_arrays`` is False, so a long replay's memory stays flat. ``progress``
    hears the stream time played so far (seconds) after every processing step.
    """
    player = Player(
        pipeline, rate=rate, block_size=block_size, on_outputs=on_outputs, keep_arrays=keep_arrays, progress=progress
    )
    for part in [rec] if isinstance(rec, Recording) else rec:
        player.feed(part)
    return player.finish()


class Player:
    """Feeds parts of a recording to the pipeline in file order, running it every half second
    of stream time; the played time, the next run's time and the pace carry over between parts."""

    def __init__(
        self,
        pipeline: MonitorPipeline,
        *,
        rate: float | None = None,
        block_size: int = DEFAULT_BLOCK_SIZE,
        on_outputs: Callable[[Outputs], None] | None = None,
        keep_arrays: bool = True,
        progress: Callable[[float], None] | None = None,
    ) -> None:
        self.pipeline = pipeline
        self.rate = rate
        self.block_size = block_size
        self.on_outputs = on_outputs
        self.keep_arrays = keep_arrays
        self.progress = progress
        self.total = Outputs()
        self.played = 0  # stream time played, ns
        self.prev_end: int | None = None  # the last block's stamp that advanced the clock
        self.next_process = PROCESS_EVERY_NS
        self.wall0 = time.perf_counter()
        self.fed = False

    def _emit(self, out: Outputs) -> None:
        self.total.extend(out if self.keep_arrays else out.light())
        if not self.keep_arrays:  # the summary's energy is its last sample: one kept, not one a step
            del self.total.energy[:-1]
        if self.on_outputs:
            self.on_outputs(out)

    def feed(self, rec: Recording) -> None:
        """One part: its markers, then its blocks, the pipeline run whenever half a second has played."""
        pipeline = self.pipeline
        for m in rec.scenarios:
            pipeline.add_marker(m)
        blocks = stream_blocks(rec, self.block_size)
        if not blocks:
            return
        if self.prev_end is None:
            self.prev_end = blocks[0][0]
        played_at = self._played(blocks)
        self.fed = True
        rate = self.rate
        i = 0
        while i < len(blocks):
            j = i  # the step: blocks i..j, then the pipeline runs
            while j + 1 < len(blocks) and played_at[j] < self.next_process:
                j += 1
            step = range(i, j + 1)
            # unpaced, a step's messages go in as one run a stream where that is the same as one by one
            runs = None if rate else _runs(rec, [blocks[k] for k in step])
            if runs is None or not pipeline.ingest_runs(runs):
                for k in step:
                    _, name, a, b = blocks[k]
                    if rate:
                        ahead = played_at[k] / NS / rate - (time.perf_counter() - self.wall0)
                        if ahead > 0:
                            time.sleep(ahead)
                    s = rec.streams[name]
                    chans = ALL_STREAMS_BY_NAME[name].channels
                    pipeline.ingest_message(name, int(s.t_ns[a]), s.period_ns, {c: s.channels[c][a:b] for c in chans})
            i = j + 1
            if played_at[j] >= self.next_process:
                # a run started at the last processing is waited for here, before this one polls its
                # outcome: when an outcome is taken, and so the order of the outputs, then never depends
                # on how fast the worker happened to be (two replays of one bag wrote the same messages
                # in other orders), and the run overlaps the feeding of the step in between
                pipeline.recalibrator.join()
                out = pipeline.process()
                self.next_process = played_at[j] + PROCESS_EVERY_NS
                self._emit(out)
                if self.progress:
                    self.progress(played_at[j] / NS)

    def _played(self, blocks: list[tuple[int, str, int, int]]) -> list[int]:
        """Stream time played after each block: stamps advance it, a clock that jumps does not."""
        played, prev_end, out = self.played, self.prev_end, []
        assert prev_end is not None
        for end_ns, _, _, _ in blocks:
            if 0 < end_ns - prev_end <= MAX_PACE_STEP_NS:
                played += end_ns - prev_end
            if end_ns > prev_end or end_ns < prev_end - MAX_PACE_STEP_NS:
                prev_end = end_ns
            out.append(played)
        self.played, self.prev_end = played, prev_end
        return out

    def finish(self) -> Outputs:
        """The final run of the pipeline (windows the recording's end cut short); the summary."""
        if self.fed:
            self.pipeline.recalibrator.join()
            self._emit(self.pipeline.process(final=True))
        return self.total


def _runs(rec: Recording, step: list[tuple[int, str, int, int]]) -> list[Run] | None:
    """A step's blocks as one run a stream, or None where a stream's blocks do not follow on
    (a jump, a gap or a duplicate: those go in one by one, where the aligner judges them)."""
    spans: dict[str, list[int]] = {}  # stream -> [start, stop, next t0, lengths...]
    for _, name, a, b in step:
        s = rec.streams[name]
        span = spans.get(name)
        if span is None:
            spans[name] = [a, b, int(s.t_ns[a]) + (b - a) * s.period_ns, b - a]
            continue
        # the aligner stamps a message t0 + k period: the next must start where those stamps go on
        if a != span[1] or int(s.t_ns[a]) != span[2]:
            return None
        span[1] = b
        span[2] += (b - a) * s.period_ns
        span.append(b - a)
    runs = []
    for name, (a, b, _, *lengths) in spans.items():
        s = rec.streams[name]
        chans = ALL_STREAMS_BY_NAME[name].channels
        x = np.empty((b - a, len(chans)), order="F")
        for col, c in enumerate(chans):
            x[:, col] = s.channels[c][a:b]
        runs.append(Run(name, int(s.t_ns[a]), s.period_ns, x, tuple(lengths)))
    return runs


def event_windows(
    rec: Recording, thresholds: StepThresholds = DEFAULT_THRESHOLDS
) -> tuple[list[EventWindow], dict[str, StreamHealth]]:
    """The recording's event windows as the online pipeline cuts them, and its streams' health.

    The recording is played as :func:`replay` plays it, with the pipeline's default settings
    (those of the nodes) on the recording's own sample period, and no recalibration.
    """
    settings = PipelineSettings(
        period_ns=rec.streams["pt_ct"].period_ns,
        detector=DetectorSettings(thresholds=thresholds),
        auto_recalibrate=False,
    )
    pipeline = MonitorPipeline(settings)
    try:
        out = replay(rec, pipeline)
        return out.windows, pipeline.health
    finally:
        pipeline.close()


def track_recording(
    rec: Recording | Iterable[Recording],
    base: GeneratorParameters,
    settings: TrackerSettings,
    on_point: Callable[[TrackPoint], None] | None = None,
) -> list[TrackPoint]:
    """The sliding-window tracker over a recording (or its parts, :mod:`phid_ros.io.parts`), as a
    node with tracking on runs it.

    X_d and X_q are held at ``base``; nothing is detected or recalibrated. ``on_point`` sees each
    hop as soon as it is estimated.
    """
    parts = iter([rec] if isinstance(rec, Recording) else rec)
    first = next(parts, None)
    if first is None:
        return []
    pipeline = MonitorPipeline(
        PipelineSettings(
            period_ns=first.streams["pt_ct"].period_ns if "pt_ct" in first.streams else PipelineSettings.period_ns,
            detect=False,
            auto_recalibrate=False,
            tracking_enabled=True,
            tracking=settings,
            tracking_base=base,
        )
    )

    def hops(out: Outputs) -> None:
        for p in out.tracked:
            on_point(p)  # type: ignore[misc]

    try:
        return replay(
            itertools.chain([first], parts), pipeline, keep_arrays=False, on_outputs=hops if on_point else None
        ).tracked
    finally:
        pipeline.close()
