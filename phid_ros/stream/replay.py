"""A recording played through the online pipeline exactly as the nodes receive it.

The one driver from a recorded (or simulated) recording to the pipeline's entry point: the
blocks go in as the sensor messages that carried them, in the order a recorder logged them.
``phid replay`` publishes what comes out; ``phid identify`` and ``phid diagnose`` take the event
windows of a recording without scenario markers from here (:func:`event_windows`), so the
windows a node would cut are the windows the batch commands use.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from phid_ros.ident.scenario import DEFAULT_THRESHOLDS, StepThresholds
from phid_ros.io.recording import DEFAULT_BLOCK_SIZE, Recording, block_bounds
from phid_ros.io.topics import STREAMS_BY_NAME
from phid_ros.model.conventions import NS
from phid_ros.model.parameters import GeneratorParameters
from phid_ros.stream.align import StreamHealth
from phid_ros.stream.detector import DetectorSettings, EventWindow
from phid_ros.stream.pipeline import MonitorPipeline, Outputs, PipelineSettings
from phid_ros.stream.tracker import TrackerSettings, TrackPoint

PROCESS_EVERY_NS = NS // 2  # stream time between pipeline runs while feeding
MAX_PACE_STEP_NS = 60 * NS  # a stamp step beyond this is a clock jump, not time to wait for


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
    progress: Callable[[float], None] | None = None,
) -> Outputs:
    """Feed every sensor block in stamp order; ``rate`` paces it at R x real time (None: as fast as possible).

    ``on_outputs`` sees every output in full; the returned summary drops the bulk arrays
    when ``keep_arrays`` is False, so a long replay's memory stays flat. ``progress`` hears
    the stream time played so far (seconds) after every processing step.
    """
    for m in rec.scenarios:
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
            # a run started in this step is waited for, so the next step polls its outcome: when an
            # outcome is taken, and so the order of the outputs, then never depends on how fast the
            # worker happened to be (two replays of one bag wrote the same messages in other orders)
            pipeline.recalibrator.join()
            next_process = played + PROCESS_EVERY_NS
            total.extend(out if keep_arrays else out.light())
            if on_outputs:
                on_outputs(out)
            if progress:
                progress(played / NS)
    out = pipeline.process(final=True)
    total.extend(out if keep_arrays else out.light())
    if on_outputs:
        on_outputs(out)
    return total


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
    rec: Recording,
    base: GeneratorParameters,
    settings: TrackerSettings,
    on_point: Callable[[TrackPoint], None] | None = None,
) -> list[TrackPoint]:
    """The sliding-window tracker over a recording, as a node with tracking on runs it.

    X_d and X_q are held at ``base``; nothing is detected or recalibrated. ``on_point`` sees each
    hop as soon as it is estimated.
    """
    pipeline = MonitorPipeline(
        PipelineSettings(
            period_ns=rec.streams["pt_ct"].period_ns,
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
        return replay(rec, pipeline, keep_arrays=False, on_outputs=hops if on_point else None).tracked
    finally:
        pipeline.close()
