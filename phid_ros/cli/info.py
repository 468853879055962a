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


class StreamTally:
    """Per-stream samples, rates, spans and gaps of a recording read in parts (``phid info`` on a day's bag):
    counts carried from part to part, a gap or a step back between two parts counted too; and
    which channels carry data, for the table of what they determine."""

    def __init__(self) -> None:
        self._streams: dict[str, dict[str, int]] = {}
        self.recorded: set[str] = set()
        self._theta = (np.inf, -np.inf)
        self.no_load = False
        self.loaded = False

    def add(self, rec: Recording) -> None:
        for name, s in rec.streams.items():
            if not len(s):
                continue
            st = self._streams.get(name)
            if st is None:
                st = self._streams[name] = {"period": s.period_ns, "samples": 0, "start": int(s.t_ns[0]), "last": 0}
                st.update(gaps=0, gap_ns=0, backwards=0)
                d = np.diff(s.t_ns)
            else:
                d = np.diff(s.t_ns, prepend=st["last"])
            gap = d > 1.5 * st["period"]
            st["samples"] += len(s)
            st["gaps"] += int(gap.sum())
            st["gap_ns"] += int((d[gap] - st["period"]).sum())
            st["backwards"] += int((d <= 0).sum())
            st["last"] = int(s.t_ns[-1])
            for c, x in s.channels.items():
                if c not in self.recorded and np.isfinite(x).any():
                    self.recorded.add(c)
        cols = {c: x for s in rec.streams.values() for c, x in s.channels.items()}
        if "theta_t" in cols and np.isfinite(cols["theta_t"]).any():
            self._theta = (
                min(self._theta[0], float(np.nanmin(cols["theta_t"]))),
                max(self._theta[1], float(np.nanmax(cols["theta_t"]))),
            )
        if "p_e" in cols and "q_e" in cols:
            current = np.hypot(cols["p_e"], cols["q_e"])
            self.no_load |= bool((current < 0.02).any())
            self.loaded |= bool((current >= 0.02).any())

    @property
    def measured(self) -> set[str]:
        """The channels with data; an angle that is 0 throughout is a recording's reference, not a measurement."""
        out = set(self.recorded)
        if not self._theta[1] > self._theta[0]:
            out.discard("theta_t")
        return out

    def summaries(self) -> list[StreamSummary]:
        return [
            StreamSummary(
                name=name,
                samples=st["samples"],
                rate_hz=NS / st["period"],
                start_ns=st["start"],
                end_ns=st["last"],
                gaps=st["gaps"],
                gap_seconds=st["gap_ns"] / NS,
                backwards=st["backwards"],
            )
            for name, st in self._streams.items()
        ]
