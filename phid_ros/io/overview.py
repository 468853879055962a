"""What a report draws of a recording, gathered part by part in bounded memory.

A replay's or a tracker's report shows V_t and P_m over the whole recording. A day at 1 kHz is
86 million samples a channel; the figure has room for a few thousand. :class:`Overview` keeps each
channel's minimum and maximum per time bin, so a 100 ms fault dip survives the decimation, and
doubles the bins' width whenever more than ``max_bins`` would be kept: its size is bounded
whatever the recording's length, and it is fed the parts of :mod:`phid_ros.io.parts` in turn.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from phid_ros.io.recording import Recording

# V_t, P_m, and P_e for a recorder that never carried P_m (a report draws it in P_m's place)
DRAWN = (("pt_ct", "v_t"), ("encoder", "p_m"), ("pt_ct", "p_e"))
MAX_BINS = 8000


class Overview:
    def __init__(self, channels: Sequence[tuple[str, str]] = DRAWN, max_bins: int = MAX_BINS) -> None:
        self.channels = tuple(channels)
        self.max_bins = max_bins
        self.start_ns: int | None = None
        self.end_ns: int | None = None
        self.width_ns = 0  # set from the first stream's period
        self._lo = {c: np.zeros(0) for _, c in self.channels}
        self._hi = {c: np.zeros(0) for _, c in self.channels}

    @classmethod
    def of(cls, rec: Recording) -> Overview:
        out = cls()
        out.add(rec)
        return out

    def add(self, rec: Recording) -> None:
        """One part of the recording (parts in file order; stamps before the first bin go in it)."""
        spans = [(int(s.t_ns[0]), int(s.t_ns[-1]), s.period_ns) for s in rec.streams.values() if len(s)]
        if not spans:
            return
        if self.start_ns is None:
            self.start_ns = min(a for a, _, _ in spans)
            self.width_ns = min(p for _, _, p in spans)
        last = max(b for _, b, _ in spans)
        self.end_ns = last if self.end_ns is None else max(self.end_ns, last)
        for stream, channel in self.channels:
            s = rec.streams.get(stream)
            if s is None or not len(s) or channel not in s.channels:
                continue
            idx = np.maximum((s.t_ns - self.start_ns) // self.width_ns, 0)
            n = int(idx.max()) + 1
            self._grow(n)
            x = s.channels[channel]
            np.fmin.at(self._lo[channel], idx, x)  # fmin/fmax: a NaN sample does not blank its bin
            np.fmax.at(self._hi[channel], idx, x)
        while max(len(v) for v in self._lo.values()) > self.max_bins:
            self._halve()

    def _grow(self, n: int) -> None:
        for c in self._lo:
            have = len(self._lo[c])
            if n > have:
                self._lo[c] = np.concatenate((self._lo[c], np.full(n - have, np.inf)))
                self._hi[c] = np.concatenate((self._hi[c], np.full(n - have, -np.inf)))

    def _halve(self) -> None:
        """Twice as wide bins, each the min and max of two."""
        self.width_ns *= 2
        for c in self._lo:
            lo, hi = self._lo[c], self._hi[c]
            if len(lo) % 2:
                lo, hi = np.append(lo, np.inf), np.append(hi, -np.inf)
            self._lo[c] = np.fmin(lo[0::2], lo[1::2])
            self._hi[c] = np.fmax(hi[0::2], hi[1::2])

    def envelope(self, channel: str) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
        """(each bin's start stamp, min, max) over the bins that hold a finite sample."""
        lo, hi = self._lo[channel], self._hi[channel]
        keep = np.flatnonzero(np.isfinite(lo) & np.isfinite(hi))
        t = (self.start_ns or 0) + keep.astype(np.int64) * self.width_ns
        return t, lo[keep], hi[keep]

    def span_ns(self) -> tuple[int, int]:
        return (self.start_ns or 0, self.end_ns or 0)
