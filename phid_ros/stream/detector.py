"""Streaming disturbance detection and event windows.

Detection runs the batch detector of :mod:`phid_ros.ident.scenario` (fault:
V_t < 0.3 V_pf; steps in P_m and in V_f, the latter only where V_t, Q or P moved with it;
sustained steps in V_t) on a sliding analysis
window, so the online pipeline and ``phid identify`` on a markerless bag find the
same events at the same samples. An event is accepted once ``settle_s`` of data
follows it (enough to see a fault clear and a step settle). Its window runs from
``pre_s`` before it to ``post_s`` after it, or to the start of the next event's window
when that comes first (a second disturbance inside a window would break the single-
event fits of every stage), or to where the recording paused (a day's test files one after
the other), and is cut from the ring buffer once detection has passed its end, so the next
event is known when the end is decided.

``phid identify`` and ``phid diagnose`` cut a recording without scenario markers through
this detector too (:func:`phid_ros.stream.replay.event_windows`): one rule for windows.

At no load (the breaker open) a fall of V_t is no fault, as a test file's events are read
(:mod:`phid_ros.ident.file_events`): one within 20 ms is the voltage measurement lost (a VT
fuse), and nothing is detected until V_t is back at 0.8 of its value before (on the Mostar
day's two such files, V_t at zero with noise made 100 "faults"); a slower one is the field
taken away, a field step.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timezone

import numpy as np
from numpy.typing import NDArray

from phid_ros.ident.file_events import (
    LOST_MEASUREMENT_S,
    MEASURED_SHARE,
    QUIET_S,
    STEP_PLATEAU_S,
    at_no_load,
    fell_at_once,
    level_before,
    moves_terminal,
    plateau_samples,
    window_start,
)
from phid_ros.ident.scenario import DEFAULT_THRESHOLDS, StepThresholds, find_events
from phid_ros.model.channels import CHANNEL_INDEX, CHANNELS, Frame
from phid_ros.model.conventions import NS, split_stamp
from phid_ros.stream.ring import RingBuffer

# The event window (paper: 1 s before the disturbance, 29 s after), one definition for the
# online detector, the node parameters and the offline cut of phid identify.
PRE_EVENT_S = 1.0
POST_EVENT_S = 29.0
# A field step (an AVR reference step, a manual field step, a de-excitation) is a staged test: its
# window reaches back for the plateau before it, as ``phid identify`` cuts a test file (halfway from
# the event before, or from where the recording resumed), up to STEP_PLATEAU_S (file_events).


@dataclass(frozen=True)
class DetectorSettings:
    pre_s: float = PRE_EVENT_S
    post_s: float = POST_EVENT_S
    plateau_s: float = STEP_PLATEAU_S  # a field step's window, back to its plateau (at most; the ring's oldest)
    settle_s: float = 2.0
    context_s: float = 3.5  # history the batch detector needs: 1 s pre-fault mean + 2 s quiet + step span
    detect_every_s: float = 1.0  # stream time between detector runs (latency: this plus settle_s)
    # the smallest P_m and V_t steps taken as disturbances (phid identify's --min-*-step)
    thresholds: StepThresholds = DEFAULT_THRESHOLDS
    # channels the recorder never carries: NaN throughout a window, they are absent, not stale
    not_recorded: frozenset[str] = frozenset()

    @property
    def lag_s(self) -> float:
        """How long after its end a window is cut at the latest: detection must have passed it."""
        return self.settle_s + self.detect_every_s


@dataclass
class Event:
    event_id: str
    kind: str
    inception_ns: int
    clearing_ns: int  # 0 when not a fault
    severity: float
    v_prefault: float
    segment: int
    # filled from a scenario marker when the recording carries one
    name: str = ""
    role: str = "identify"
    generator_damping: bool = True
    # what the test sheet says of the scenario (a marker's): who held the field, the reference step
    regulator: str = ""
    reference_step: float | None = None


def event_id(kind: str, inception_ns: int) -> str:
    """An event's identity: what happened and when, by the stream's clock.

    The same disturbance replayed or re-ingested after a restart gets the same id (so the
    store recognises it); ids never restart per process, unlike a counter would.
    """
    sec, ns = split_stamp(inception_ns)
    stamp = datetime.fromtimestamp(sec, tz=timezone.utc).strftime("%Y-%m-%dT%H:%M:%S")
    return f"{kind}@{stamp}.{ns:09d}Z"


@dataclass(kw_only=True)
class EventWindow(Frame):
    """The frame around one event, as cut from the ring buffer (keyword construction only)."""

    event: Event
    usable: bool = True
    reason: str = ""
    # V_t's and Q's step as a test sheet states it (``settled_steps``), for the reader; not published
    settled: dict[str, float] = field(default_factory=dict)
    # a recorder's own channels on the window's stamps (the field current, the regulator's and the
    # stabiliser's outputs: :mod:`phid_ros.stream.recorder`), those it kept
    recorded: dict[str, NDArray[np.float64]] = field(default_factory=dict)

    def light(self) -> EventWindow:
        """The window without its samples (new empty arrays: a slice would keep them alive)."""
        return EventWindow(
            t_ns=np.empty(0, np.int64),
            values=np.empty((0, self.values.shape[1])),
            period_ns=self.period_ns,
            event=self.event,
            usable=self.usable,
            reason=self.reason,
            settled=self.settled,
        )


SETTLED = ("v_t", "q_e")
STEP_KINDS = ("voltage_step", "field_step")


def settled_steps(w: Frame, inception_ns: int) -> dict[str, float]:
    """V_t's and Q's step between the second before the event and the last quarter of the window
    after it: the size a test sheet gives (an AVR step of +5 % and back, a manual field step). The
    event's severity is its first 0.2 s, before a regulator has settled: on the commissioning day's
    no-load +10 % step it read +0.051 pu for the sheet's +0.10. ``w`` runs from the plateau before
    the event to the second before the next event's (not a field step's window, which stops
    halfway to it and read +0.047 for the +5 % step with the stabiliser on)."""
    k = int(np.searchsorted(w.t_ns, inception_ns))
    after = len(w.t_ns) - k
    if k < 2 or after < 8:
        return {}
    second = max(2, int(NS // w.period_ns))
    out = {}
    for name in SETTLED:
        x = w.channel(name)
        pre, tail = x[max(0, k - second) : k], x[k + (3 * after) // 4 :]
        if np.isfinite(pre).any() and np.isfinite(tail).any():
            out[name] = float(np.nanmean(tail) - np.nanmean(pre))
    return out


@dataclass
class Detector:
    ring: RingBuffer
    period_ns: int
    settings: DetectorSettings = field(default_factory=DetectorSettings)
    _frontier_ns: int | None = None
    _segment: int = 0
    _pending: list[Event] = field(default_factory=list)
    _last_cut: Event | None = None  # the event before the pending ones in this segment: where they start
    # a pending field step's window start and the boundary before it, once decided
    _starts: dict[str, tuple[int, int]] = field(default_factory=dict)
    # the voltage measurement lost at no load: V_t before it, and (once back) until when the
    # events are the measurement's, not the machine's (None: not lost)
    _lost_level: float | None = None
    _lost_until_ns: int | None = None
    lost_measurements: list[tuple[int, int | None]] = field(default_factory=list)  # (lost at, back at), for the record

    def reset(self, segment: int) -> None:
        """A new segment (clock jump): nothing before it can be part of a window after it."""
        self._frontier_ns = None
        self._segment = segment
        self._pending = [e for e in self._pending if e.segment == segment]
        self._last_cut = None
        self._starts.clear()
        self._lost_level = self._lost_until_ns = None

    def update(self, *, force: bool = False) -> tuple[list[Event], list[EventWindow]]:
        """New events since the last call, and windows whose post-event time has passed.

        Detection steps through stream time ``detect_every_s`` at a time, each step reading its
        own span and ``settle_s`` after it (with ``force``, also the part step up to what is
        decided): what is found depends on the data alone, not on how often this is called. A
        node at 20x (called every 2 s of stream time) found a step on a test file's edge that
        ``phid replay`` (every 0.5 s) did not.
        """
        latest = self.ring.latest_ns
        if latest is None:
            return [], []
        s = self.settings
        new: list[Event] = []
        decided = latest - int(s.settle_s * NS)
        if self._frontier_ns is None:
            # from the start of a segment, events can be found once the pre-event mean exists
            oldest = self.ring.oldest_ns
            self._frontier_ns = (oldest if oldest is not None else latest) + int(s.pre_s * NS)
        step = int(s.detect_every_s * NS)
        while decided > self._frontier_ns:
            end = self._frontier_ns + step
            if end > decided:
                if not force:
                    break
                end = decided
            self._detect(self._frontier_ns, end, new)
            self._frontier_ns = end
        self._pending.extend(new)
        windows = []
        still: list[Event] = []
        for ev, (start, end), reading in zip(self._pending, self._spans(), self._readings()):
            # every event before the end is known once detection has passed it
            if self._frontier_ns > end and not still:
                windows.append(self._cut(ev, start, end, reading=reading))
                self._last_cut = ev
            else:
                still.append(ev)
        self._pending = still
        return new, windows

    def _detect(self, start: int, end: int, new: list[Event]) -> None:
        """Events in [``start``, ``end``), read on the span from ``context_s`` before it to
        ``settle_s`` after it."""
        s = self.settings
        t, x = self.ring.window(start - int(s.context_s * NS), end + int(s.settle_s * NS))
        if len(t) <= 10:
            return
        # the batch detector reads V_t and P_m; P and Q say whether the breaker is open
        # (V_f too: an AVR reference step or a manual field step moves V_t by 1 % only)
        signals = {c: forward_filled(x[:, CHANNEL_INDEX[c]]) for c in ("v_t", "p_m", "p_e", "q_e", "v_f")}
        no_load: bool | None = None  # read where a fault asks: a median over the span costs
        dt = self.period_ns / NS
        for kind, k, k_cl in find_events(signals, dt, thresholds=s.thresholds):
            if not start <= t[k] < end or self._measurement_lost(t, signals["v_t"], k):
                continue
            if kind == "field_step" and not moves_terminal(signals, k, dt):
                continue  # a static exciter's ripple: the field channel moved, the machine did not
            if kind == "fault" and no_load is None:
                no_load = at_no_load(signals)
            if no_load and kind == "fault":
                if fell_at_once(signals["v_t"], k, dt):
                    self._lose_measurement(t, signals["v_t"], k)
                    continue
                kind = "field_step"  # a de-excitation: the field taken away
            new.append(self._event(kind, t, signals, k, k_cl))
        if self._lost_level is not None and self._lost_until_ns is None:
            self._measurement_back(t, signals["v_t"], end)

    def _lose_measurement(self, t: NDArray[np.int64], v: NDArray[np.float64], k: int) -> None:
        self._lost_level = level_before(v, k, max(1, int(NS / self.period_ns)))
        self._lost_until_ns = None
        self.lost_measurements.append((int(t[k]), None))
        self._measurement_back(t, v, int(t[-1]) + 1)

    def _measurement_back(self, t: NDArray[np.int64], v: NDArray[np.float64], decided: int) -> None:
        """Whether V_t came back (0.8 of its level before the loss) after the loss and before
        ``decided``: then the events of the next QUIET_S (the return's own step) are still the
        measurement's."""
        assert self._lost_level is not None
        lost_at, _ = self.lost_measurements[-1]
        back = np.flatnonzero((v >= MEASURED_SHARE * self._lost_level) & (t > lost_at) & (t < decided))
        if back.size:
            at = int(t[int(back[0])])
            self._lost_until_ns = at + int(QUIET_S * NS)
            self.lost_measurements[-1] = (lost_at, at)

    def _measurement_lost(self, t: NDArray[np.int64], v: NDArray[np.float64], k: int) -> bool:
        """An event while the measurement is lost, or on its return: none of the machine's."""
        if self._lost_level is None:
            return False
        if self._lost_until_ns is None:
            self._measurement_back(t, v, int(t[k]) + 1)
            if self._lost_until_ns is None:
                return True
        if int(t[k]) <= self._lost_until_ns:
            return True
        self._lost_level = self._lost_until_ns = None  # back, and quiet since
        return False

    def flush(self) -> tuple[list[Event], list[EventWindow]]:
        """End of input: detect what can still be decided, and cut every waiting window as it is.

        A window the end of the data cuts short is still usable when it holds ``settle_s`` after
        its event (what the detector needed to accept it); the stages judge whether it is enough.
        """
        new, windows = self.update(force=True)
        out = windows + [
            self._cut(ev, a, b, final=True, reading=r)
            for ev, (a, b), r in zip(self._pending, self._spans(), self._readings())
        ]
        self._last_cut = self._pending[-1] if self._pending else self._last_cut
        self._pending = []
        return new, out

    def _start(self, before: Event | None, ev: Event) -> tuple[int, int]:
        """Where ``ev``'s window begins, and the stamp before which ``before``'s ends: ``pre_s``
        before it (the paper's 1 s) for both. A field step, a staged test, is cut as ``phid
        identify`` cuts a test file's events (:func:`~phid_ros.ident.file_events.window_start`,
        counted in samples as there): from where the recording resumed when it paused after
        ``before`` (another test's file; the ring's oldest without one), else from the sample
        halfway from ``before``'s end to it, where ``before``'s window ends; its own window from its
        plateau there, never more than ``plateau_s`` back."""
        s = self.settings
        if ev.kind != "field_step":
            t0 = ev.inception_ns - int(s.pre_s * NS)
            return t0, t0
        if ev.event_id in self._starts:
            return self._starts[ev.event_id]
        dt = self.period_ns / NS
        cap = plateau_samples(dt, max(s.pre_s, s.plateau_s))
        # twice the cap back: a midpoint further than that is beyond the cap anyway
        lo = ev.inception_ns - (2 * cap + 2) * self.period_ns
        before_end = None if before is None else (before.clearing_ns or before.inception_ns)
        after = int(max(2.0, 1.5 * s.pre_s) * NS)  # plateau_start reads the event's first second
        t, x = self.ring.window(max(lo, before_end) if before_end is not None else lo, ev.inception_ns + after)
        k = int(np.searchsorted(t, ev.inception_ns))
        if k < 2:  # nothing before it held (the ring cleared): the paper's pre-event time
            t0 = ev.inception_ns - int(s.pre_s * NS)
            return t0, t0
        judged = [i for i, c in enumerate(CHANNELS) if c not in s.not_recorded]
        paused = np.flatnonzero(~np.isfinite(x[:k, judged]).any(axis=1))
        if paused.size:
            boundary = int(paused[-1]) + 1  # the recording resumed: this test's file begins
        elif before_end is None or before_end < int(t[0]):
            boundary = 0  # the ring's oldest, or twice the cap back: the cap decides
        else:  # the sample halfway, as a file's events are counted: (k_before + k) // 2
            j = int(np.searchsorted(t, before_end))
            boundary = j + (k - j) // 2
        signals = {c: x[:, CHANNEL_INDEX[c]] for c in ("v_t", "q_e", "p_e")}
        first = min(window_start(signals, min(boundary, k), k, dt, max(s.pre_s, s.plateau_s)), k - 1)
        start = min(int(t[max(first, 0)]), ev.inception_ns - int(s.pre_s * NS))
        if before_end is None or paused.size:
            ends_before = start
        elif before_end >= int(t[0]):
            ends_before = int(t[min(boundary, k)])
        else:  # halfway lies before what was read (beyond the cap): on the grid, counted from ``before``
            ends_before = before_end + ((ev.inception_ns - before_end) // self.period_ns // 2) * self.period_ns
        # the ring holds what lies before the event once it is detected: decided once
        self._starts[ev.event_id] = (start, min(ends_before, start))
        return self._starts[ev.event_id]

    def _spans(self) -> list[tuple[int, int]]:
        """Each pending window's first and last stamp: from its start (:meth:`_start`) to ``post_s``
        after its event or the sample before the next window's boundary."""
        post = int(self.settings.post_s * NS)
        bounds = [self._start(b, ev) for b, ev in zip([self._last_cut, *self._pending[:-1]], self._pending)]
        ends = [ev.inception_ns + post - self.period_ns for ev in self._pending]
        for i in range(len(ends) - 1):
            ends[i] = min(ends[i], bounds[i + 1][1] - self.period_ns)
        return [(start, end) for (start, _), end in zip(bounds, ends)]

    def _readings(self) -> list[int]:
        """Each pending step's last stamp for its settled size: ``post_s`` after it, or the
        second before the next event (past a field step's window, which stops halfway)."""
        s = self.settings
        ends = [ev.inception_ns + int(s.post_s * NS) - self.period_ns for ev in self._pending]
        for i in range(len(ends) - 1):
            ends[i] = min(ends[i], self._pending[i + 1].inception_ns - int(s.pre_s * NS) - self.period_ns)
        return ends

    def _event(
        self, kind: str, t: NDArray[np.int64], sig: dict[str, NDArray[np.float64]], k: int, k_cl: int | None
    ) -> Event:
        n_pre = max(1, int(1.0 * NS / self.period_ns))
        v_pf = float(np.mean(sig["v_t"][max(0, k - n_pre) : k])) if k > 0 else float(sig["v_t"][0])
        span = max(1, int(0.2 * NS / self.period_ns))
        if kind == "fault":
            stop = k_cl if k_cl is not None else len(t)
            severity = 1.0 - float(np.min(sig["v_t"][k:stop])) / v_pf
        else:
            x = sig["p_m"] if kind == "torque_step" else sig["v_t"]
            severity = float(np.mean(x[k : k + span]) - np.mean(x[max(0, k - span) : k]))
        return Event(
            event_id=event_id(kind, int(t[k])),
            kind=kind,
            inception_ns=int(t[k]),
            clearing_ns=int(t[k_cl]) if (kind == "fault" and k_cl is not None) else 0,
            severity=severity,
            v_prefault=v_pf,
            segment=self._segment,
        )

    def _cut(self, ev: Event, t0: int, t1: int, *, final: bool = False, reading: int | None = None) -> EventWindow:
        s = self.settings
        if t0 < ev.inception_ns - int(s.pre_s * NS) and self.ring.oldest_ns is not None:
            t0 = max(t0, self.ring.oldest_ns)  # a plateau reaching back past the ring's oldest sample
        self._starts.pop(ev.event_id, None)
        t, x = self.ring.window(t0, t1)
        t, x = t.copy(), x.copy()
        latest = self.ring.latest_ns or 0
        expected = grid_points(t0, t1, self.period_ns, latest if self.ring.latest_ns is not None else t0)
        w = EventWindow(t_ns=t, values=x, period_ns=self.period_ns, event=ev)
        if ev.segment != self._segment:
            w.usable, w.reason = False, "the clock jumped (new segment) before the window was complete"
        elif len(t) < expected and latest < t1:
            short = (t1 - latest) / NS
            w.reason = f"the data ended {short:.1f} s before the end of the window"
            have = int(round((latest - t0) / self.period_ns)) + 1
            if not final or latest - ev.inception_ns < int(s.settle_s * NS) or len(t) < have:
                w.usable = False
        elif len(t) < expected:
            w.usable, w.reason = False, f"window has {len(t)} of {expected} samples (ring buffer too short or gap)"
        judged = [i for i, c in enumerate(CHANNELS) if c not in s.not_recorded]
        if w.usable and len(x):
            w = self._paused_trimmed(w, judged)
        stale = stale_data(w.values, s.not_recorded) if w.usable else ""
        if stale:
            w.usable, w.reason = False, stale
        if w.usable and ev.kind in STEP_KINDS:
            w.settled = settled_steps(self._reading(ev, w, reading), ev.inception_ns)
        return w

    def _reading(self, ev: Event, w: EventWindow, end: int | None) -> Frame:
        """The samples a step's settled size is read on: its window's, on to ``end`` where the
        recording did not pause before it."""
        if end is None or len(w.t_ns) == 0 or end <= int(w.t_ns[-1]):
            return w
        t, x = self.ring.window(int(w.t_ns[0]), end)
        judged = [i for i, c in enumerate(CHANNELS) if c not in self.settings.not_recorded]
        paused = np.flatnonzero(~np.isfinite(x[:, judged]).any(axis=1) & (t > ev.inception_ns))
        stop = int(paused[0]) if paused.size else len(t)
        return Frame(t[:stop], x[:stop], self.period_ns)

    def _paused_trimmed(self, w: EventWindow, judged: list[int]) -> EventWindow:
        """The window between the recording's pauses around its event (rows where every channel
        judged is missing: a commissioning day's files one after the other, minutes apart, the
        next file another test); shortened as a window the data's end cuts, usable when the
        event keeps half its pre-event time and ``settle_s`` after it. A gap in which some
        channels go on is a gap, and the window stays stale."""
        recorded: NDArray[np.bool_] = np.asarray(np.isfinite(w.values[:, judged]).any(axis=1))
        n = len(w.t_ns)
        if recorded.all() or not recorded.any():
            return w
        k = int(np.searchsorted(w.t_ns, w.event.inception_ns))
        paused = np.flatnonzero(~recorded)
        before, after = paused[paused < k], paused[paused >= k]
        first = int(before[-1]) + 1 if before.size else 0
        last = int(after[0]) - 1 if after.size else n - 1
        if first == 0 and last == n - 1:
            return w
        s, ev = self.settings, w.event
        t0, t1 = int(w.t_ns[first]), int(w.t_ns[max(first, last)])
        rows = slice(first, last + 1)
        out = EventWindow(t_ns=w.t_ns[rows].copy(), values=w.values[rows].copy(), period_ns=w.period_ns, event=ev)
        why = []
        # said only within the paper's pre-event time: a field step's plateau begins where its file does
        if first and t0 > ev.inception_ns - int(s.pre_s * NS):
            why.append(f"the recording resumed {(t0 - int(w.t_ns[0])) / NS:.1f} s into the window")
        if last < n - 1:
            why.append(f"paused {(int(w.t_ns[-1]) - t1) / NS:.1f} s before its end")
        out.reason = "; ".join(why)
        if ev.inception_ns - t0 < int(0.5 * s.pre_s * NS) or t1 - ev.inception_ns < int(s.settle_s * NS):
            out.usable = False
            out.reason += ": too little of the window left around the event"
        return out


def stale_data(values: NDArray[np.float64], not_recorded: frozenset[str]) -> str:
    """Why a window's samples cannot be used (a dead channel, gaps), or "" when they can: the
    one judgement, for the detector's cut and for a window that arrives by topic. A channel the
    recorder never carries is absent, not dead."""
    judged = [i for i, c in enumerate(CHANNELS) if c not in not_recorded]
    if np.isfinite(values[:, judged]).all():
        return ""
    finite = np.isfinite(values)
    dead = [CHANNELS[i] for i in judged if len(values) and not finite[:, i].any()]
    gappy = [CHANNELS[i] for i in judged if finite[:, i].any() and not finite[:, i].all()]
    why = [f"no data on {', '.join(dead)} (a dead channel)"] if dead else []
    why += [f"{gappy} have gaps"] if gappy else []
    return "stale data in the window: " + "; ".join(why)


def grid_points(t0: int, t1: int, period_ns: int, anchor: int) -> int:
    """How many samples of the grid ``anchor + k period_ns`` lie in [t0, t1]. A window's bounds are
    not on the grid (a trend log at 4.8 ms: the inception less 2 s): rounding the span over the
    period counted one sample more than the grid holds half the time, and refused every window."""
    k_min = -((anchor - t0) // period_ns)  # ceil((t0 - anchor) / period)
    k_max = (t1 - anchor) // period_ns
    return max(0, k_max - k_min + 1)


def window_status(w: EventWindow) -> str:
    """A window's state in one phrase: ok, ok but shortened (and why), or why it is not used."""
    if not w.usable:
        return w.reason
    return f"ok, shortened: {w.reason}" if w.reason else "ok"


def lost_measurement_text(lost_ns: int, back_ns: int | None, start_ns: int | None = None, *, ended: bool) -> str:
    """What the front ends say of a V_t measurement lost at no load (``Detector.lost_measurements``):
    times from ``start_ns`` in seconds, else as stamps; ``ended``: the input is over."""

    def at(t: int) -> str:
        return f"{(t - start_ns) / NS:.1f} s" if start_ns is not None else f"stamp {t} ns"

    until = f"back at {at(back_ns)}" if back_ns is not None else ("not back by the end" if ended else "not back yet")
    return (
        f"V_t measurement lost at no load at {at(lost_ns)}, {until}: no event taken from it "
        f"(an open-circuit voltage cannot fall within {LOST_MEASUREMENT_S * 1e3:.0f} ms)"
    )


def severity_text(kind: str, severity: float, settled: dict[str, float] | None = None) -> str:
    """An event's size in its own terms: a fault's dip of V_t, a step's change of P_m, a voltage or
    field step's settled change of V_t and Q where its window gave them (else its first 0.2 s)."""
    if kind == "fault":
        return f"V_t -{100 * severity:.0f}%"
    if settled and kind in STEP_KINDS and "v_t" in settled:
        # both: a dip that recovers within its window settles near 0, a regulator's step after 0.2 s
        text = f"ΔV_t {settled['v_t']:+.3f} pu" + (f", ΔQ {settled['q_e']:+.3f}" if "q_e" in settled else "")
        return text + f" settled ({severity:+.3f} at 0.2 s)"
    return f"{'ΔP_m' if kind == 'torque_step' else 'ΔV_t'} {severity:+.3f} pu"


def forward_filled(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Forward-fill NaN gaps (leading ones take the first finite value) for detection only."""
    bad = ~np.isfinite(x)
    if not bad.any():
        return x
    idx = np.where(~bad, np.arange(len(x)), 0)
    np.maximum.accumulate(idx, out=idx)
    out = x[idx]
    first = np.flatnonzero(~bad)
    if first.size:
        out[: first[0]] = x[first[0]]
    else:
        out[:] = 0.0
    return out
