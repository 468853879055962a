"""What is in a recording: per-stream samples, rates, spans, gaps and stamp problems."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from phid_ros.io.recording import Recording
from phid_ros.model.conventions import NS


@dataclass(frozen=True)
class StreamSummary:
    name: str
    samples: int
    rate_hz: float
    start_ns: int
    end_ns: int
    gaps: int
    gap_seconds: float
    backwards: int  # stamps not after their predecessor (duplicates, out of order, clock jumps)


def summarise_streams(rec: Recording) -> list[StreamSummary]:
    out: list[StreamSummary] = []
    for name, s in rec.streams.items():
        d = np.diff(s.t_ns)
        gap = d > 1.5 * s.period_ns
        out.append(
            StreamSummary(
                name=name,
                samples=len(s),
                rate_hz=NS / s.period_ns,
                start_ns=int(s.t_ns[0]) if len(s) else 0,
                end_ns=int(s.t_ns[-1]) if len(s) else 0,
                gaps=int(gap.sum()),
                gap_seconds=float((d[gap] - s.period_ns).sum() / NS),
                backwards=int((d <= 0).sum()),
            )
        )
    return out
