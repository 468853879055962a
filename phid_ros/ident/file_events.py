"""Every event of a test file: a commissioning test's recording, cut into one window per event.

A real test file holds several events: an AVR reference step and its return 6-10 s later, a
ramp and then a step, a de-excitation. The paper's scenario has one event and takes its
post-event steady state from the final fifth of the window; over a step-and-return file that
mixes both plateaus (and the return's transient), so each event is cut into its own window:
from the midpoint of the plateau before it (at most a minute back) to the midpoint of the plateau after it, its
steady state the second half of the span after the event (the windows do not overlap, so no
plateau counts twice).

A terminal voltage that falls at no load within a few samples is a lost voltage measurement
(a VT fuse, a breaker in the VT circuit), not the machine: an open-circuit machine's voltage
follows its field flux, which cannot fall that fast. Such an event's window is left out, by
name.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from phid_ros.ident.scenario import DEFAULT_THRESHOLDS, STEP_NOISE_SIGMAS, StepThresholds, find_events
from phid_ros.model.channels import NO_LOAD_CURRENT, current_of

Array = NDArray[np.float64]
QUIET_S = 2.0  # two detections closer than this are one event seen in two signals
MIN_WINDOW_S = 2.0  # an event with less than this between its neighbours is not cut on its own
# a no-load V_t that loses half its value within this is a measurement lost, not flux decaying
# (the fastest open-circuit decay is the subtransient one, T''_d0 of tens of ms, and only with
# the field short-circuited)
LOST_MEASUREMENT_S = 0.02
# ... and V_t at this share of its level the second before counts as measured: not yet lost
# just before the fall, back once it returns (the events of the next QUIET_S are the return's)
MEASURED_SHARE = 0.8
# the plateau before an event: its level over the last PLATEAU_LEVEL_S, left where a channel
# strays from it by more than PLATEAU_SHARE of the event's own move
PLATEAU_LEVEL_S = 1.0
PLATEAU_SHARE = 0.2
MIN_TERMINAL_MOVE = 0.002  # pu: an event moves V_t, Q or P by at least this (a 1 % field step moves V_t 1.4 %)
# a window reaches back for the plateau before its event at most this far: the field circuit's k_e
# and the exciter's initial state are read there (1 s of it made the exciter's ceilings 3 % off),
# and the online detector's ring holds no more (``DetectorSettings.plateau_s``); one rule for both
STEP_PLATEAU_S = 60.0


def plateau_samples(dt: float, plateau_s: float = STEP_PLATEAU_S) -> int:
    """How many samples before its event a window reaches back at most."""
    return max(1, int(round(plateau_s / dt)))


def window_start(
    signals: Mapping[str, Array], boundary: int, k: int, dt: float, plateau_s: float = STEP_PLATEAU_S
) -> int:
    """Where the window of the event at ``k`` begins: its plateau (:func:`plateau_start`) from
    ``boundary`` (the file's start, or halfway from the event before), at most ``plateau_s`` back.
    The online detector cuts a field step's window by this function too, so a test file's events
    and the monitor's give the same samples to the stages and to ``phid validate``."""
    return plateau_start(signals, max(boundary, k - plateau_samples(dt, plateau_s)), k, dt)


@dataclass(frozen=True)
class FileEvent:
    kind: str
    start: int  # the window's first sample in the file
    event: int  # the event's sample in the file
    end: int  # one past the window's last sample
    steady_start: int  # where its post-event steady state begins, in the file
    lost_measurement: bool = False
    # later detections made before it settled, taken as its own transient: (kind, sample) each
    joined: tuple[tuple[str, int], ...] = ()

    def describe(self, dt: float) -> str:
        return f"{self.kind} at {self.event * dt:.2f} s (window {self.start * dt:.2f}-{self.end * dt:.2f} s)"

    def joined_note(self, dt: float) -> str:
        """What was taken into this event as its own transient ("" where nothing was)."""
        if not self.joined:
            return ""
        named = ", ".join(f"{kind} at {k * dt:.2f} s" for kind, k in self.joined)
        return f"the {named} came before the {self.kind} at {self.event * dt:.2f} s had settled: part of it, one event"


def event_note(e: FileEvent, dt: float, file: str) -> str:
    """The note a scenario cut from a file's event carries (its time there: ``ScenarioData.file_time_s``)."""
    return f"event {e.describe(dt)} of {file}"


def events_of_file(
    signals: Mapping[str, Array], dt: float, *, thresholds: StepThresholds = DEFAULT_THRESHOLDS
) -> list[FileEvent]:
    """The file's events, each with its own window (empty when the signals show none). At no
    load a fall of V_t is a de-excitation (a field step) or a lost measurement, never a fault."""
    n = len(signals["v_t"])
    no_load = at_no_load(signals)
    found = find_events(signals, dt, quiet_s=QUIET_S, thresholds=thresholds)
    # a fault and a step found on its recovery are one event: keep the first of each quiet span
    events: list[tuple[str, int, int | None]] = []
    quiet = int(round(QUIET_S / dt))
    for e in found:
        last = events[-1] if events else None
        end_of_last = None if last is None else (last[2] if last[2] is not None else last[1])
        if end_of_last is not None and e[1] - end_of_last < quiet:
            continue
        events.append(e)
    events = [e for e in events if moves_terminal(signals, e[1], dt)]
    joined: dict[int, list[tuple[str, int]]] = {}
    events = _own_transients_joined(signals, events, dt, joined)
    out: list[FileEvent] = []
    v = np.asarray(signals["v_t"], float)
    lost_until = -1
    for i, (kind, k, k_clear) in enumerate(events):
        k_end = k_clear if k_clear is not None else k
        start = window_start(signals, 0 if i == 0 else (_last_end(events[i - 1]) + k) // 2, k, dt)
        end = n if i == len(events) - 1 else (k_end + events[i + 1][1]) // 2
        if (end - start) * dt < MIN_WINDOW_S or k - start < 2:
            continue
        # the measurement's return is an event of the measurement too
        lost = (lost_until >= 0 and k <= lost_until + quiet) or (no_load and kind == "fault" and fell_at_once(v, k, dt))
        if lost and k >= lost_until:  # lost until the measurement comes back
            back = np.flatnonzero(v[k:] >= MEASURED_SHARE * level_before(v, k, max(1, int(round(1.0 / dt)))))
            lost_until = k + int(back[0]) if back.size else n
        if no_load and kind == "fault":
            kind = "field_step"
        out.append(FileEvent(kind, start, k, end, (k_end + end) // 2, lost, tuple(joined.get(k, ()))))
    return out


def _own_transients_joined(
    signals: Mapping[str, Array],
    events: list[tuple[str, int, int | None]],
    dt: float,
    joined: dict[int, list[tuple[str, int]]],
) -> list[tuple[str, int, int | None]]:
    """The events, each later detection made while the one before it has not settled left out:
    a disturbance's own transient (a limit its exciter reaches, the regulator's answer, the swing,
    the field forced through a build-up from standstill) is part of its event, never a second
    one. A fault's swing cut at its exciter's limit 2.4 s on lost stage 1 its H (-19 %); a
    build-up's field forcing and its arrival at the set-point, cut apart, gave T'_d0 0.36 s.
    ``joined`` gets, by the kept event's sample, the detections taken into it."""
    kept: list[tuple[str, int, int | None]] = []
    for e in events:
        if kept and not settled(signals, kept[-1][1], _last_end(kept[-1]), e[1], dt):
            joined.setdefault(kept[-1][1], []).append((e[0], e[1]))
            continue
        kept.append(e)
    return kept


SETTLE_S = 1.0  # the span whose activity says whether a transient has settled
SMOOTH_S = 0.1  # activity is read on the signal's 0.1 s mean: noise is not a transient
SETTLED_SHARE = 0.2  # settled: the second before the next event moves less than this share of the first second after
QUIET_SIGMAS = 3.0  # ... or no more than this many times the channel's own activity before the event


def settled(signals: Mapping[str, Array], k: int, k_end: int, k_next: int, dt: float) -> bool:
    """Whether the event at ``k`` (over at ``k_end``: a fault's clearing) has settled by
    ``k_next``. Each of V_t, Q, P and the speed that the event moved (its activity over the
    SETTLE_S after ``k_end`` more than five times its activity before ``k``; activity is the
    std of the signal's SMOOTH_S mean) must move over the SETTLE_S before ``k_next`` by less than
    SETTLED_SHARE of that, or no more than QUIET_SIGMAS times its activity before the event.
    A commissioning test's return 6-10 s after its step has settled; a swing still decaying, a
    regulator still forcing, a build-up still rising has not."""
    w = max(3, int(round(SETTLE_S / dt)))
    m = max(1, int(round(SMOOTH_S / dt)))
    if k - w < 0 or k_next - w < k_end:
        return k_next - w >= k_end  # too little before the event to judge: apart once a span has passed
    kernel = np.ones(m) / m
    for c in ("v_t", "q_e", "p_e", "omega"):
        if c not in signals:
            continue
        x = np.asarray(signals[c], float)

        def activity(a: int, b: int) -> float:
            # only the span judged is smoothed (the spans between may be hours long)
            lo, hi = max(0, a - m), min(len(x), b + m)
            mean = np.convolve(x[lo:hi], kernel, mode="same") if m > 1 else x[lo:hi]
            return float(np.std(mean[a - lo : b - lo]))

        if not all(np.isfinite(x[a:b]).all() for a, b in ((k - w, k), (k_end, k_end + w), (k_next - w, k_next))):
            continue
        before, early, late = activity(k - w, k), activity(k_end, k_end + w), activity(k_next - w, k_next)
        if early > 5.0 * before and late > SETTLED_SHARE * early and late > QUIET_SIGMAS * before:
            return False
    return True


def plateau_start(signals: Mapping[str, Array], start: int, k: int, dt: float) -> int:
    """Where the plateau before the event at ``k`` begins, no earlier than ``start``: one past the
    last sample at which the channel the event moves most (V_t, Q or P) stood further from its
    level just before the event than PLATEAU_SHARE of the event's move. A manual test's Q ramp
    100 s before its field step is not the step's steady state: averaged in, Mostar's
    RR_MR_Step10 read Q 0.12 pu before a step taken at 0.045, and its play-in started 0.38 pu away
    from the recording. (The channels it barely moves, P at a field step, wander by more than a
    fifth of their move and say nothing of where the test began.)"""
    lead = max(2, int(round(PLATEAU_LEVEL_S / dt)))
    span = max(5, int(round(0.5 / dt)))
    if k - start <= 2 * lead or k + span + span // 2 > len(signals["v_t"]):
        return start
    moves: dict[str, tuple[float, float]] = {}
    for c in ("v_t", "q_e", "p_e"):
        x = np.asarray(signals[c], float)
        if np.isfinite(x[start : k + 2 * span]).all():
            level = float(np.median(x[k - lead : k]))
            moves[c] = (level, abs(float(np.mean(x[k + span // 2 : k + span + span // 2])) - level))
    if not moves:
        return start
    c, (level, move) = max(moves.items(), key=lambda m: m[1][1])
    if move < MIN_TERMINAL_MOVE:
        return start
    x = np.asarray(signals[c], float)
    off = np.flatnonzero(np.abs(x[start : k - lead] - level) > PLATEAU_SHARE * move)
    return start + int(off[-1]) + 1 if off.size else start


def at_no_load(signals: Mapping[str, Array]) -> bool:
    """The stator current is below the no-load threshold over the signals (the breaker open)."""
    return bool(np.median(current_of(signals)) < NO_LOAD_CURRENT)


def moves_terminal(signals: Mapping[str, Array], k: int, dt: float) -> bool:
    """Whether V_t, Q or P moved at the event by more than their noise allows (a field channel's
    ripple, a static exciter's, can pass the step threshold with nothing happening to the machine)."""
    span = max(5, int(round(0.5 / dt)))
    for c in ("v_t", "q_e", "p_e"):
        x = np.asarray(signals[c], float)
        if not np.isfinite(x).all():
            continue
        a, b = x[max(0, k - span) : k], x[k + span // 2 : k + span + span // 2]
        if len(a) < 5 or len(b) < 5:
            continue
        sigma = float(np.median(np.abs(np.diff(x[max(0, k - 4 * span) : k])))) / (0.6745 * np.sqrt(2.0))
        floor = STEP_NOISE_SIGMAS * max(sigma, 1e-6) * np.sqrt(2.0 / span)
        if abs(float(np.mean(b) - np.mean(a))) > max(floor, MIN_TERMINAL_MOVE):
            return True
    return False


def _last_end(e: tuple[str, int, int | None]) -> int:
    return e[2] if e[2] is not None else e[1]


def fell_at_once(v: Array, k: int, dt: float) -> bool:
    """V_t lost half its pre-event value within LOST_MEASUREMENT_S of the event: at no load, a
    measurement lost (an open-circuit machine's voltage follows its field flux, never that fast)."""
    before = level_before(v, k, max(1, int(round(1.0 / dt))))
    m = max(1, int(round(LOST_MEASUREMENT_S / dt)))
    a = max(0, k - m)
    return (
        bool(np.min(v[a : k + m + 1]) < 0.5 * before and np.max(v[a:k]) > MEASURED_SHARE * before) if k > a else False
    )


def level_before(v: Array, k: int, span: int) -> float:
    """V_t's level before sample ``k``: the median of the ``span`` samples before it (the first
    sample at the start), what a lost measurement is judged against and must come back to."""
    return float(np.median(v[max(0, k - span) : k])) if k > 0 else float(v[0])
