"""A fixed-capacity ring buffer of aligned samples: stamps plus one column per channel, out as frames.

Appending a block is O(block) with at most two slice copies, whatever the fill;
memory is allocated once (``capacity`` rows), so a replay of any length stays flat.
Windows by time come back as views when they do not wrap, copies when they do.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from phid_ros.model.channels import Frame


class RingBuffer:
    def __init__(self, capacity: int, channels: Sequence[str], period_ns: int = 0) -> None:
        if capacity < 1:
            raise ValueError("capacity must be at least 1")
        self.capacity = int(capacity)
        self.channels = tuple(channels)
        self.period_ns = int(period_ns)  # of the frames handed out (0: not said)
        self._t = np.zeros(self.capacity, dtype=np.int64)
        self._x = np.zeros((self.capacity, len(self.channels)), dtype=np.float64)
        self._head = 0  # next write position
        self._size = 0
        self.total_written = 0  # samples ever appended: a monotonic sample counter

    def __len__(self) -> int:
        return self._size

    def append(self, t_ns: NDArray[np.int64], values: NDArray[np.float64]) -> None:
        """Append a block: ``t_ns`` (n,), ``values`` (n, channels); older samples fall off the end."""
        n = len(t_ns)
        if n == 0:
            return
        if n >= self.capacity:
            t_ns, values, n = t_ns[-self.capacity :], values[-self.capacity :], self.capacity
        first = min(n, self.capacity - self._head)
        self._t[self._head : self._head + first] = t_ns[:first]
        self._x[self._head : self._head + first] = values[:first]
        rest = n - first
        if rest:
            self._t[:rest] = t_ns[first:]
            self._x[:rest] = values[first:]
        self._head = (self._head + n) % self.capacity
        self._size = min(self.capacity, self._size + n)
        self.total_written += n

    def clear(self) -> None:
        self._head = 0
        self._size = 0

    def _ordered_index(self, start: int, stop: int) -> slice | NDArray[np.int64]:
        """Storage positions of logical rows [start, stop) (0 = oldest kept)."""
        base = (self._head - self._size) % self.capacity
        a, b = base + start, base + stop
        if b <= self.capacity:
            return slice(a, b)
        if a >= self.capacity:
            return slice(a - self.capacity, b - self.capacity)
        return np.concatenate((np.arange(a, self.capacity), np.arange(0, b - self.capacity)))

    def rows(self, start: int, stop: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Logical rows [start, stop): views when contiguous, copies when wrapped."""
        start, stop = max(0, start), min(self._size, stop)
        if stop <= start:
            return np.zeros(0, np.int64), np.zeros((0, len(self.channels)))
        idx = self._ordered_index(start, stop)
        return self._t[idx], self._x[idx]

    def stamps(self) -> NDArray[np.int64]:
        return self.rows(0, self._size)[0]

    def _search(self, t_ns: int, side: str) -> int:
        """Logical index of ``t_ns`` by binary search in the (at most two) stored runs, no copy."""
        base = (self._head - self._size) % self.capacity
        first = self._t[base : base + min(self._size, self.capacity - base)]
        k = int(np.searchsorted(first, t_ns, side=side))  # type: ignore[call-overload]
        if k < len(first) or len(first) == self._size:
            return k
        return len(first) + int(np.searchsorted(self._t[: self._size - len(first)], t_ns, side=side))  # type: ignore[call-overload]

    def window(self, t0_ns: int, t1_ns: int) -> Frame:
        """Samples with t0 <= t <= t1 (the buffer holds increasing stamps)."""
        return Frame(*self.rows(self._search(t0_ns, "left"), self._search(t1_ns, "right")), self.period_ns)

    @property
    def latest_ns(self) -> int | None:
        return int(self._t[(self._head - 1) % self.capacity]) if self._size else None

    @property
    def oldest_ns(self) -> int | None:
        return int(self._t[(self._head - self._size) % self.capacity]) if self._size else None
