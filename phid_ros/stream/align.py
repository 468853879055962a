"""Align the four sensor streams on one uniform time grid, and keep their health.

Each stream arrives as blocks (start stamp, sample period, arrays) with its own
clock and rate. The aligner accepts samples per stream, then emits grid points
once every stream has data past them; a stream value on the grid is its own
sample when the stamps coincide, else a linear interpolation between the
bracketing samples when they are at most ``max_bracket`` apart (the
approximate-time idea of message_filters, for continuous signals), else NaN
(a gap, counted).

Bad input is dropped sample by sample and counted, never written into the
buffer: non-finite values, values implausible for per unit (a kV or A feed by
mistake), duplicate stamps (a stamp already accepted), stamps that go backwards
a little (out of order), and zero stamps (an unset clock, not a time).

Clock faults. A block whose stamp jumps back by more than ``jump_back_ns`` or
ahead by more than ``hold_ahead_ns`` is not trusted at once: it is held until
the stream's next block says which clock is right. If the next block continues
the held one, the clock really jumped: back, or ahead by more than
``max_gap_ns``, starts a new segment (the aligner flushes and restarts, and the
consumer is told, ``segment`` increments, so no window spans the jump); ahead by
less is a gap. If the next block continues the old time, the held block was a
single wild stamp: it is dropped and counted. The grid therefore never spans
more than ``max_gap_ns`` of missing data, whatever the stamps say, so memory
stays bounded.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from phid_ros.io.topics import STREAMS, STREAMS_BY_NAME
from phid_ros.model.channels import CHANNEL_INDEX, CHANNELS, PLAUSIBLE, Frame
from phid_ros.model.conventions import NS
from phid_ros.stream.levels import Level, worst

RATE_BLOCKS = 50  # blocks a stream's rate is measured over
GAP_SPANS = 10_000  # gaps remembered per stream to tell a pause from a loss (more are counted as losses)


@dataclass
class StreamHealth:
    """Counters and rate of one input stream (diagnostic_updater's frequency and stamp status)."""

    name: str
    expected_rate_hz: float = 1000.0
    messages: int = 0
    samples: int = 0
    accepted: int = 0
    duplicates: int = 0
    out_of_order: int = 0
    nonfinite: int = 0
    implausible: int = 0
    zero_stamps: int = 0  # samples of messages stamped 0: an unset clock, not a time
    wild_stamps: int = 0  # samples of a block whose stamp jumped and came straight back
    malformed: int = 0  # samples of messages whose channel arrays differ in length (the longest counted)
    # samples kept with a channel that had no finite value in the whole message (a dead sensor
    # channel beside live ones: its samples are NaN, a gap on that channel only, not dropped)
    dead_channel: int = 0
    # every channel of the stream declared not recorded (PipelineSettings.not_recorded): a plant
    # without a speed encoder has no encoder stream to go stale
    not_recorded: bool = False
    gaps: int = 0
    missing: int = 0  # samples absent in those gaps (by the stamps): what was lost on the way
    # of those, the gaps that lie between two marked scenarios (a test recorder's files one after
    # the other): the recording paused, nothing was lost (see :meth:`mark_pauses`)
    pauses: int = 0
    paused_missing: int = 0
    clock_jumps: int = 0
    gap_grid_points: int = 0
    last_stamp_ns: int | None = None
    last_receive_ns: int | None = None
    lag_ns: int = 0
    # the last RATE_BLOCKS blocks (stamp of the last sample, samples) and their sample total: the
    # diagnostics ask for the rate once a second per stream, the aligner adds a block per message
    _recent: deque[tuple[int, int]] = field(default_factory=lambda: deque(maxlen=RATE_BLOCKS))
    _recent_samples: int = 0
    # (last stamp before, first stamp after, samples missing) of each gap, the last GAP_SPANS
    _gap_spans: deque[tuple[int, int, int]] = field(default_factory=lambda: deque(maxlen=GAP_SPANS))

    @property
    def dropped(self) -> int:
        return (
            self.duplicates
            + self.out_of_order
            + self.nonfinite
            + self.implausible
            + self.zero_stamps
            + self.wild_stamps
            + self.malformed
        )

    def note_block(self, last_stamp_ns: int, samples: int) -> None:
        if len(self._recent) == RATE_BLOCKS:
            self._recent_samples -= self._recent[0][1]
        self._recent.append((last_stamp_ns, samples))
        self._recent_samples += samples

    def forget_blocks(self) -> None:
        self._recent.clear()
        self._recent_samples = 0

    def note_gap(self, before_ns: int, after_ns: int, missing: int) -> None:
        """A hole in the stream between two accepted stamps; the rate is judged from after it (a
        rate over a pause read 171 Hz for a 208 Hz recorder)."""
        self.gaps += 1
        self.missing += missing
        self._gap_spans.append((before_ns, after_ns, missing))
        self.forget_blocks()

    def mark_pauses(self, marked: Sequence[tuple[int, int]]) -> None:
        """Count as pauses the gaps that touch no marked scenario (``marked``: their [start, end]
        stamps): the recording paused between two tests, nothing was lost. Without markers every
        gap is a loss: a live feed has no pauses by design."""
        pauses = [g for g in self._gap_spans if marked and not any(a < g[1] and g[0] < b for a, b in marked)]
        self.pauses = len(pauses)
        self.paused_missing = sum(g[2] for g in pauses)

    def rate_hz(self) -> float:
        """Samples per second over the recent blocks, by their stamps."""
        if len(self._recent) < 2:
            return float("nan")
        span = self._recent[-1][0] - self._recent[0][0]
        n = self._recent_samples - self._recent[0][1]  # the first block's samples end at its stamp
        return n * NS / span if span > 0 else float("nan")

    def status(
        self,
        now_ns: int | None = None,
        *,
        stream_now_ns: int | None = None,
        rate_tolerance: float = 0.1,
        stale_ns: int = 2 * NS,
        max_lag_ns: int = NS,
    ) -> tuple[Level, str]:
        """(level, message): OK, WARN, ERROR or STALE, as diagnostic_updater reports.

        ``now_ns`` is the receiver's clock (live nodes); ``stream_now_ns`` the newest stamp of
        any stream, which also works on a replayed recording where nothing is received late.
        """
        if self.not_recorded:
            return Level.OK, "not recorded here (declared)"
        if self.last_stamp_ns is None:
            return Level.STALE, "no data yet"
        if now_ns is not None and self.last_receive_ns is not None and now_ns - self.last_receive_ns > stale_ns:
            return Level.STALE, f"no data for {(now_ns - self.last_receive_ns) / NS:.1f} s"
        if stream_now_ns is not None and stream_now_ns - self.last_stamp_ns > stale_ns:
            return Level.STALE, f"no samples for {(stream_now_ns - self.last_stamp_ns) / NS:.1f} s of stream time"
        rate = self.rate_hz()
        problems = []
        level = Level.OK
        if np.isfinite(rate) and abs(rate - self.expected_rate_hz) > rate_tolerance * self.expected_rate_hz:
            problems.append(f"rate {rate:.0f} Hz, expected {self.expected_rate_hz:.0f} Hz")
            level = worst(level, Level.WARN)
        if self.lag_ns > max_lag_ns:
            problems.append(f"stamp lag {self.lag_ns / NS:.2f} s")
            level = worst(level, Level.WARN)
        if self.dropped:
            problems.append(
                f"{self.dropped} samples dropped (dup {self.duplicates}, order {self.out_of_order}, "
                f"non-finite {self.nonfinite}, implausible {self.implausible}, zero stamp {self.zero_stamps}, "
                f"wild stamp {self.wild_stamps}, malformed {self.malformed})"
            )
            level = worst(level, Level.WARN)
        if self.dead_channel:
            problems.append(f"{self.dead_channel} samples with a dead channel (no finite value in their message)")
            most = self.samples and self.dead_channel > 0.5 * self.samples
            level = worst(level, Level.ERROR if most else Level.WARN)
        if self.missing > self.paused_missing:
            problems.append(f"{self.missing - self.paused_missing} samples missing in {self.gaps - self.pauses} gap(s)")
            level = worst(level, Level.WARN)
        if self.samples and self.dropped > 0.5 * self.samples:
            level = worst(level, Level.ERROR)
        said = "; ".join(problems) or f"{rate:.0f} Hz"
        if self.pauses:  # said, not judged: a pause between two tests is the recording's design
            said += f"; paused {self.pauses} time(s) between marked tests"
        return level, said

    def as_dict(self) -> dict[str, object]:
        return {k: v for k, v in self.__dict__.items() if not k.startswith("_")} | {"rate_hz": self.rate_hz()}


@dataclass
class AlignedBlock(Frame):
    """A run of grid points every stream has passed; ``segment`` counts the clock jumps before it."""

    segment: int = 0


class _Pending:
    """Accepted samples of one stream not yet consumed by the grid."""

    def __init__(self, channels: tuple[str, ...]) -> None:
        self.channels = channels
        self.t: list[NDArray[np.int64]] = []
        self.x: list[NDArray[np.float64]] = []
        self.period_ns = 0  # the stream's own sample period, as its latest message said

    def add(self, t: NDArray[np.int64], x: NDArray[np.float64]) -> None:
        if len(t):
            self.t.append(t)
            self.x.append(x)

    def arrays(self) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        if len(self.t) > 1:
            self.t = [np.concatenate(self.t)]
            self.x = [np.concatenate(self.x)]
        if not self.t:
            return np.zeros(0, np.int64), np.zeros((0, len(self.channels)))
        return self.t[0], self.x[0]

    def drop_before(self, t_ns: int) -> None:
        t, x = self.arrays()
        k = int(np.searchsorted(t, t_ns, side="left"))
        k = max(0, k - 1)  # keep the left bracket
        if k:
            self.t, self.x = [t[k:]], [x[k:]]

    def clear(self) -> None:
        self.t, self.x = [], []

    @property
    def latest(self) -> int | None:
        return int(self.t[-1][-1]) if self.t else None


@dataclass
class _Held:
    """A block whose stamp jumped, waiting for the stream's next block to confirm or refute it."""

    t: NDArray[np.int64]
    x: NDArray[np.float64]
    period_ns: int


@dataclass(frozen=True)
class Run:
    """Consecutive messages of one stream, each starting one period after the one before."""

    stream: str
    t0_ns: int
    period_ns: int
    x: NDArray[np.float64]  # (samples, the stream's channels), column-major as :meth:`Aligner.ingest` builds it
    lengths: tuple[int, ...]  # samples of each message, in order


RECENT_STAMPS = 20_000  # accepted stamps remembered per stream to tell a duplicate from a late sample


class _RecentStamps:
    """The last ``RECENT_STAMPS`` accepted stamps of a stream, in a fixed circular array.

    Order does not matter (only membership is asked), so a block is written at the cursor:
    keeping them by concatenate-and-trim copied 160 kB per message, the aligner's largest cost.
    """

    EMPTY = np.iinfo(np.int64).min  # never a stamp: the clock starts at zero

    def __init__(self) -> None:
        self._t = np.full(RECENT_STAMPS, self.EMPTY, np.int64)
        self._at = 0

    def add(self, t: NDArray[np.int64]) -> None:
        t = t[-RECENT_STAMPS:]
        first = min(len(t), RECENT_STAMPS - self._at)
        self._t[self._at : self._at + first] = t[:first]
        self._t[: len(t) - first] = t[first:]
        self._at = (self._at + len(t)) % RECENT_STAMPS

    def contains(self, t: NDArray[np.int64]) -> NDArray[np.bool_]:
        return np.isin(t, self._t)

    def clear(self) -> None:
        self._t.fill(self.EMPTY)
        self._at = 0


class Aligner:
    def __init__(
        self,
        period_ns: int = 1_000_000,
        *,
        max_bracket_ns: int | None = None,
        jump_back_ns: int = NS,
        hold_ahead_ns: int = NS,
        max_gap_ns: int = 60 * NS,
        stale_ns: int = NS,
        expected_rates_hz: Mapping[str, float] | None = None,
        not_recorded: frozenset[str] = frozenset(),
    ):
        self.period_ns = int(period_ns)
        self.max_bracket_ns = int(max_bracket_ns if max_bracket_ns is not None else 5 * period_ns)
        self.jump_back_ns = int(jump_back_ns)
        self.hold_ahead_ns = int(hold_ahead_ns)
        self.max_gap_ns = int(max_gap_ns)
        self.stale_ns = int(stale_ns)
        rates = dict(expected_rates_hz or {})
        self.health = {s.name: StreamHealth(s.name, rates.get(s.name, NS / period_ns)) for s in STREAMS}
        # per stream, which of its channels the recorder never carries: not dead when they are NaN
        self._absent = {s.name: np.array([c in not_recorded for c in s.channels]) for s in STREAMS}
        for s in STREAMS:
            self.health[s.name].not_recorded = bool(self._absent[s.name].all())
        self._pending = {s.name: _Pending(s.channels) for s in STREAMS}
        self._held: dict[str, _Held | None] = {s.name: None for s in STREAMS}
        self._recent_t = {s.name: _RecentStamps() for s in STREAMS}
        self._limits = {
            s.name: (np.array([PLAUSIBLE[c][0] for c in s.channels]), np.array([PLAUSIBLE[c][1] for c in s.channels]))
            for s in STREAMS
        }
        self.segment = 0
        self._max_stamp = 0
        self._next_grid: int | None = None
        self._out: list[AlignedBlock] = []

    @property
    def stream_now_ns(self) -> int | None:
        """The newest accepted stamp of any stream: the stream clock that staleness is judged on."""
        stamps = [h.last_stamp_ns for h in self.health.values() if h.last_stamp_ns is not None]
        return max(stamps) if stamps else None

    def status(self, name: str, now_ns: int | None = None) -> tuple[Level, str]:
        """One stream's diagnostic level and message, stale judged on both clocks."""
        return self.health[name].status(now_ns, stream_now_ns=self.stream_now_ns, stale_ns=self.stale_ns)

    # -- input -------------------------------------------------------------------------
    def ingest(
        self,
        stream: str,
        t0_ns: int,
        period_ns: int,
        arrays: Mapping[str, NDArray[np.float64]],
        receive_ns: int | None = None,
    ) -> None:
        spec = STREAMS_BY_NAME[stream]
        h = self.health[stream]
        lengths = [len(arrays[c]) for c in spec.channels]
        n = max(lengths)
        h.messages += 1
        h.samples += n
        if min(lengths) != n:
            h.malformed += n  # no sample of it can be placed: which array lost which value is unknown
            return
        # one message's columns side by side, each contiguous (column-major): filled by copies, checked
        # column by column (row-major, every row is a 2-4 element inner loop: 10x slower on a whole stream)
        x = np.empty((n, len(spec.channels)), order="F")
        for j, c in enumerate(spec.channels):
            x[:, j] = arrays[c]
        if n == 0:
            return
        if int(t0_ns) == 0 and self._max_stamp > self.jump_back_ns:
            h.zero_stamps += n  # an unset clock in a stream that had real stamps: not a time, not a jump
            return
        t = int(t0_ns) + np.arange(n, dtype=np.int64) * int(period_ns)
        self._max_stamp = max(self._max_stamp, int(t[-1]))
        if receive_ns is not None:
            h.last_receive_ns = int(receive_ns)
            h.lag_ns = int(receive_ns) - int(t[-1])
        held = self._held[stream]
        if held is not None:
            self._held[stream] = None
            if 0 < t[0] - held.t[-1] <= self.hold_ahead_ns + held.period_ns:
                self._confirm_jump(stream, held)  # the clock really jumped: this block goes on from there
            else:
                h.wild_stamps += len(held.t)  # one block off and straight back: a wild stamp
        last = h.last_stamp_ns
        if last is not None and (t[0] < last - self.jump_back_ns or t[0] > last + self.hold_ahead_ns):
            if t[-1] - t[0] < self.hold_ahead_ns:
                self._held[stream] = _Held(t, x, int(period_ns))
                return
            # a block spanning more than the hold is its own witness: one wild header stamp shifts
            # one message, not a second of consistently stamped samples (batch reads feed whole runs)
            self._confirm_jump(stream, _Held(t, x, int(period_ns)))
            return
        self._check_and_accept(stream, h, t, x, int(period_ns))

    def take_runs(self, runs: Sequence[Run]) -> bool:
        """Several streams' runs of messages at once, exactly as :meth:`ingest` would take them
        one message at a time in any interleaving; False, with nothing taken, when that cannot
        be promised (the caller then feeds the messages one by one).

        Promised when every run would take :meth:`ingest`'s common path message by message:
        a stream with an accepted stamp, no held block, the run starting one period after that
        stamp, every sample within its plausible range. Then no message of the runs can hold,
        jump, start a segment or leave a hole, so the order of streams does not matter, and the
        counters, the rate blocks, the recent stamps and the pending samples come out the same.
        Why: a replay fed 26 400 messages one by one, about 20 us each in the aligner.
        """
        for r in runs:
            h = self.health[r.stream]
            if (
                not 0 < r.period_ns <= self.hold_ahead_ns
                or self._held[r.stream] is not None
                or h.last_stamp_ns is None
                or r.t0_ns != h.last_stamp_ns + r.period_ns
                or len(r.x) != sum(r.lengths)
            ):
                return False
            lo, hi = self._limits[r.stream]
            if not ((r.x >= lo).all() and (r.x <= hi).all()):  # NaN compares False: refused too
                return False
        for r in runs:
            h = self.health[r.stream]
            n = len(r.x)
            h.messages += len(r.lengths)
            h.samples += n
            t = r.t0_ns + np.arange(n, dtype=np.int64) * r.period_ns
            self._max_stamp = max(self._max_stamp, int(t[-1]))
            h.accepted += n
            h.last_stamp_ns = int(t[-1])
            end = r.t0_ns - r.period_ns
            for k in r.lengths:  # the rate is judged over the last messages, not the last runs
                end += k * r.period_ns
                h.note_block(end, k)
            self._recent_t[r.stream].add(t)
            self._pending[r.stream].add(t, r.x)
            self._pending[r.stream].period_ns = r.period_ns
        return True

    def _confirm_jump(self, stream: str, held: _Held) -> None:
        h = self.health[stream]
        last = h.last_stamp_ns
        if last is not None and (held.t[0] < last - self.jump_back_ns or held.t[0] > last + self.max_gap_ns):
            h.clock_jumps += 1
            self._new_segment()  # back in time, or so far ahead that a grid over the hole makes no sense
        self._check_and_accept(stream, h, held.t, held.x, held.period_ns)

    def _check_and_accept(
        self, stream: str, h: StreamHealth, t: NDArray[np.int64], x: NDArray[np.float64], period_ns: int
    ) -> None:
        last = h.last_stamp_ns
        lo, hi = self._limits[stream]
        # the common case, a clean block in order, in four array operations (a comparison with NaN
        # is False, without numpy's warning); sample by sample only when not
        if period_ns > 0 and (last is None or t[0] > last) and (x >= lo).all() and (x <= hi).all():
            self._accept(stream, h, t, x, period_ns, regular=True)
            return
        n = len(t)
        if h.not_recorded and not np.isfinite(x).any():
            return  # a stream the recorder never carries: its empty messages are neither data nor loss
        dead = ~np.isfinite(x).any(axis=0) if n > 1 else np.zeros(x.shape[1], dtype=bool)
        if dead.any() and not dead.all():
            # a channel dead for the whole message: its samples kept as NaN, the live channels judged
            x = x.copy()
            x[:, dead] = np.nan
            if (dead & ~self._absent[stream]).any():  # a channel never recorded is not a dead one
                h.dead_channel += n
            live = ~dead
            x_live, lo, hi = x[:, live], lo[live], hi[live]
        else:
            x_live = x
        with np.errstate(invalid="ignore"):
            plausible = ((x_live >= lo) & (x_live <= hi)).all(axis=1)  # False for NaN too
        ok = np.ones(n, dtype=bool)
        finite = np.isfinite(x_live).all(axis=1)
        h.nonfinite += int((~finite).sum())
        ok &= finite
        bad_range = finite & ~plausible
        h.implausible += int(bad_range.sum())
        ok &= plausible
        # not newer than what came before: a duplicate when that stamp was accepted, else late
        prev = np.maximum.accumulate(np.concatenate(([last if last is not None else np.iinfo(np.int64).min], t)))[:-1]
        stale = ok & (t <= prev)
        seen = self._recent_t[stream].contains(t) | (t == prev)
        dup = stale & seen
        back = stale & ~seen
        h.duplicates += int(dup.sum())
        h.out_of_order += int(back.sum())
        ok &= ~stale
        t_ok, x_ok = t[ok], x[ok]
        if len(t_ok) == 0:
            return
        self._accept(stream, h, t_ok, x_ok, period_ns)

    def _accept(
        self,
        stream: str,
        h: StreamHealth,
        t: NDArray[np.int64],
        x: NDArray[np.float64],
        period_ns: int,
        regular: bool = False,
    ) -> None:
        """``regular``: ``t`` is a whole message's stamps, evenly ``period_ns`` apart, so a hole can
        only open before its first sample."""
        if regular:
            first = int(t[0]) - h.last_stamp_ns if h.last_stamp_ns is not None else 0
            holes = np.array([first]) if first > 1.5 * period_ns else np.zeros(0, np.int64)
        else:
            steps = np.diff(t) if h.last_stamp_ns is None else np.diff(np.concatenate(([h.last_stamp_ns], t)))
            holes = steps[steps > 1.5 * period_ns]
        if holes.size:
            stamps = t if h.last_stamp_ns is None else np.concatenate(([h.last_stamp_ns], t))
            for k in np.flatnonzero(np.diff(stamps) > 1.5 * period_ns):
                hole = int(stamps[k + 1] - stamps[k])
                h.note_gap(int(stamps[k]), int(stamps[k + 1]), int(round(hole / period_ns)) - 1)
        h.accepted += len(t)
        h.last_stamp_ns = int(t[-1])
        h.note_block(int(t[-1]), len(t))
        self._recent_t[stream].add(t)
        self._pending[stream].add(t, x)
        self._pending[stream].period_ns = int(period_ns)

    def _new_segment(self) -> None:
        self.flush()
        for p in self._pending.values():
            p.clear()
        for h in self.health.values():
            h.last_stamp_ns = None
            h.forget_blocks()
        for recent in self._recent_t.values():
            recent.clear()
        self._next_grid = None
        self.segment += 1

    # -- output ------------------------------------------------------------------------
    def pull(self, *, final: bool = False) -> list[AlignedBlock]:
        """Grid points that every stream has passed (or, with ``final``, everything left)."""
        if final:
            # the input has ended: a held block has no successor to refute it, so it stands
            for name, held in self._held.items():
                if held is not None:
                    self._held[name] = None
                    self._confirm_jump(name, held)
        self._align(final)
        out, self._out = self._out, []
        return out

    def flush(self) -> None:
        self._align(final=True)

    def _align(self, final: bool) -> None:
        latest = {name: p.latest for name, p in self._pending.items()}
        have = [v for v in latest.values() if v is not None]
        if not have:
            return
        if self._next_grid is None:
            firsts = [int(p.arrays()[0][0]) for p in self._pending.values() if p.t]
            if len(firsts) < len(self._pending) and not final and max(have) - min(firsts) <= self.stale_ns:
                # wait until every stream has started, but not for one that sends nothing usable (a
                # dead channel, every sample NaN): waiting for it held every other stream's samples
                # back to the end and the ring buffer kept only the last of them (14 of 18 events lost)
                return
            start = max(firsts)
            self._next_grid = -(-start // self.period_ns) * self.period_ns
        newest = max(have)
        if final:
            end = newest
        else:
            # a stream that fell more than stale_ns behind the others does not hold the grid back
            live = [v for v in have if v >= newest - self.stale_ns]
            end = min(live)
            if len(live) < len(self._pending):
                end = min(end, newest - self.stale_ns)
        if end < self._next_grid:
            return
        grid = np.arange(self._next_grid, end + 1, self.period_ns, dtype=np.int64)
        if grid.size == 0:
            return
        # a channel contiguous, as Frame.of_columns; every column is written below (no NaN fill first)
        values = np.empty((grid.size, len(CHANNELS)), order="F")
        unset = set(range(len(CHANNELS)))
        for name, p in self._pending.items():
            cols = [CHANNEL_INDEX[c] for c in p.channels]
            unset.difference_update(cols)
            t, x = p.arrays()
            if t.size == 0:
                values[:, cols] = np.nan
                self.health[name].gap_grid_points += grid.size
                continue
            # a stream slower than the grid (a 50 Hz PMU beside 1 kHz PT/CT) is interpolated between its
            # own samples; a gap is a hole of more than max_bracket_ns or five of its own periods
            values[:, cols] = self._sample(t, x, grid, max(self.max_bracket_ns, 5 * p.period_ns))
            self.health[name].gap_grid_points += int(np.isnan(values[:, cols[0]]).sum())
            p.drop_before(int(grid[-1]))
        values[:, sorted(unset)] = np.nan  # a channel no stream carries (none today)
        self._next_grid = int(grid[-1]) + self.period_ns
        self._out.append(AlignedBlock(grid, values, self.period_ns, self.segment))

    def _sample(
        self, t: NDArray[np.int64], x: NDArray[np.float64], grid: NDArray[np.int64], max_bracket_ns: int
    ) -> NDArray[np.float64]:
        # fast path: the stream sits on the grid itself (same clock and rate)
        k0 = int(np.searchsorted(t, grid[0]))
        if (
            k0 + grid.size <= t.size
            and t[k0] == grid[0]
            and t[k0 + grid.size - 1] == grid[-1]
            and np.array_equal(t[k0 : k0 + grid.size], grid)
        ):
            return x[k0 : k0 + grid.size]
        right = np.searchsorted(t, grid, side="left")
        exact = (right < t.size) & (t[np.minimum(right, t.size - 1)] == grid)
        left = np.clip(right - 1, 0, t.size - 1)
        right_c = np.clip(right, 0, t.size - 1)
        span = t[right_c] - t[left]
        ok = (right > 0) & (right < t.size) & (span <= max_bracket_ns)
        w = np.where(ok & (span > 0), (grid - t[left]) / np.where(span > 0, span, 1), 0.0)
        out = x[left] + (x[right_c] - x[left]) * w[:, None]
        out[~(ok | exact)] = np.nan
        out[exact] = x[right_c[exact]]
        return out
