"""``phid replay``: play a recording through the online pipeline, exactly as the nodes run it."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from phid_ros.io.recording import DEFAULT_BLOCK_SIZE, NS, Recording, block_bounds
from phid_ros.io.topics import STREAMS_BY_NAME
from phid_ros.stream.pipeline import Marker, MonitorPipeline, Outputs

PROCESS_EVERY_NS = NS // 2  # stream time between pipeline runs while feeding


def markers_of(rec: Recording) -> list[Marker]:
    return [Marker(s.name, s.kind, s.role, s.generator_damping, s.start_ns, s.end_ns) for s in rec.scenarios]


def sensor_blocks(rec: Recording, block_size: int = DEFAULT_BLOCK_SIZE) -> list[tuple[int, str, int, int]]:
    """(stamp of the block's last sample, stream, start, stop), in the order a recorder logged them."""
    blocks = []
    for name, s in rec.streams.items():
        for a, b in block_bounds(s.t_ns, s.period_ns, block_size):
            blocks.append((int(s.t_ns[b - 1]), name, a, b))
    blocks.sort(key=lambda x: x[0])
    return blocks


def replay(
    rec: Recording,
    pipeline: MonitorPipeline,
    *,
    rate: float | None = None,
    block_size: int = DEFAULT_BLOCK_SIZE,
    on_outputs: Callable[[Outputs], None] | None = None,
) -> Outputs:
    """Feed every sensor block in stamp order; ``rate`` paces it at R x real time (None: as fast as possible)."""
    for m in markers_of(rec):
        pipeline.add_marker(m)
    total = Outputs()
    blocks = sensor_blocks(rec, block_size)
    if not blocks:
        return total
    wall0, stream0 = time.perf_counter(), blocks[0][0]
    next_process = stream0 + PROCESS_EVERY_NS
    for end_ns, name, a, b in blocks:
        s = rec.streams[name]
        spec = STREAMS_BY_NAME[name]
        if rate:
            ahead = (end_ns - stream0) / NS / rate - (time.perf_counter() - wall0)
            if ahead > 0:
                time.sleep(ahead)
        pipeline.ingest(name, int(s.t_ns[a]), s.period_ns, {c: s.channels[c][a:b] for c in spec.channels})
        if end_ns >= next_process:
            out = pipeline.process()
            next_process = end_ns + PROCESS_EVERY_NS
            total.extend(out)
            if on_outputs:
                on_outputs(out)
    out = pipeline.process(final=True)
    total.extend(out)
    if on_outputs:
        on_outputs(out)
    return total


def event_times(outputs: Outputs) -> np.ndarray:
    return np.array([e.inception_ns for e in outputs.events], dtype=np.int64)
