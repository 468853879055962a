"""The unit's model on file checked against every disturbance the monitor sees.

A recalibration answers "what is the machine now?"; a planning engineer is asked another
question: is the record the transmission operator simulates (the unit's ``.dyr``) still right?
MOD-026/027 ask it every few years and after changes, MOD-033 against real events; the tools
that answer it play an event's recorded V and f into the model offline. Here every usable event
window is played into the record as ``phid validate`` plays it (the same function:
:class:`phid_ros.api.RecordOnFile`, injected as ``play`` since the record's reader sits beside
this layer), and the verdict is kept, published and judged:

- **OK** while the record passes every check of the last ``window`` events;
- **WARN** when it failed a check on ``warn_events`` of the last ``window`` events;
- **ERROR** when a check of those events failed by more than ``error_bands`` times its band;

and, where a recalibration determines a parameter the record carries, a difference of more
than ``drift_sigmas`` of its std is said (:meth:`RecordCheck.compare`), so that a stale record
is found before a planner meets it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from phid_ros.controls.unit_validation import CHANNELS, ChannelCheck, ScenarioCheck, UnitValidation
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.terminal import at_no_load
from phid_ros.model.parameters import PARAMETER_NAMES, SYMBOLS, GeneratorParameters
from phid_ros.stream.detector import EventWindow
from phid_ros.stream.levels import Level

OK, WARN, ERROR = Level.OK, Level.WARN, Level.ERROR
MAX_OVERLAYS = 8  # failing events whose traces are kept for the report
# the scenarios kept to read the field's base from, and to play again when it changes: every
# no-load test (up to this many; the base is read from them) and the latest on-line events (a
# 30 s window at 1 kHz is about 3 MB: a monitor running for months must not keep them all)
KEPT_NO_LOAD = 50
KEPT_RECENT = 20
PLAYED_IN = ("v_t", "p_e", "q_e")  # what an event needs to be played into the record and checked


@dataclass(frozen=True)
class RecordCheckSettings:
    window: int = 5  # the last n events judged
    warn_events: int = 2  # k of them failing a check: WARN
    error_bands: float = 2.0  # a check failed beyond this many bands: ERROR
    drift_sigmas: float = 2.0  # identified and record differ by more than this many stds: drifting
    open_loop: bool = False  # the exciter driven by the recorded V_t (phid validate --open-loop)

    def __post_init__(self) -> None:
        if not 1 <= self.warn_events <= self.window:
            raise ValueError(f"warn_events {self.warn_events} must be between 1 and window {self.window}")
        if not self.error_bands >= 1.0 or not self.drift_sigmas > 0:
            raise ValueError("error_bands must be at least 1 and drift_sigmas positive")


@dataclass
class EventVerdict:
    """One event played into the record: each check, as ``phid validate``'s JSON holds it."""

    event_id: str
    kind: str
    stream_time_ns: int  # the window's end: when the verdict could be given
    record: str  # what was played in, one line
    checks: list[ChannelCheck]
    notes: list[str]
    # the record's state once this event was judged (as /diagnostics says it), and its drift then
    level: Level = OK
    status: str = ""
    drifting: list[str] = field(default_factory=list)
    # the traces of a failing event (recorded, simulated), for the report's overlays; kept for the
    # first MAX_OVERLAYS failing events only, so a long replay's memory does not grow with them
    overlay: ScenarioCheck | None = field(default=None, repr=False)

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)

    @property
    def checked(self) -> bool:
        return bool(self.checks)

    def worst(self) -> ChannelCheck | None:
        """The check furthest outside (or least inside) its band."""
        return max(self.checks, key=lambda c: c.max_error / c.band if c.band > 0 else math.inf, default=None)

    def failed(self) -> list[ChannelCheck]:
        return [c for c in self.checks if not c.passed]

    def as_json(self) -> dict[str, Any]:
        return {
            "event_id": self.event_id,
            "kind": self.kind,
            "stream_time_ns": self.stream_time_ns,
            "record": self.record,
            "passed": self.passed,
            "checks": [c.as_json() for c in self.checks],
            "notes": self.notes,
            "level": str(self.level),
            "status": self.status,
            "drifting": self.drifting,
        }


@dataclass
class RecordDrift:
    """A parameter the recalibration determined away from the record's value (D in the record's
    torque form, PSS/E's)."""

    name: str
    record: float
    identified: float
    std: float

    @property
    def sigmas(self) -> float:
        return abs(self.identified - self.record) / self.std

    def text(self) -> str:
        change = 100.0 * (self.identified / self.record - 1.0) if self.record else math.nan
        return (
            f"{SYMBOLS[self.name]}: record {self.record:.4g}, identified {self.identified:.4g} ± {self.std:.2g} "
            f"({change:+.1f} %, {self.sigmas:.1f} std)"
        )


Player = Callable[[Sequence[ScenarioData], float], UnitValidation]


FieldBase = Callable[[list[ScenarioData]], tuple[list[ScenarioData], list[str]]]


def _unchanged(scenarios: list[ScenarioData]) -> tuple[list[ScenarioData], list[str]]:
    return scenarios, []


@dataclass
class RecordCheck:
    """The record on file, the verdicts of the events played into it, and its state.

    ``play`` plays scenarios into the record (``RecordOnFile.play`` with the settings' loop);
    ``to_scenario`` makes a window the scenario ``phid validate`` would cut; ``on_base`` puts
    the recorded E_fd on the record's machine base as validate does, from every no-load test
    among the scenarios (``RecordOnFile.on_machine_base``); ``parameters_at`` is the record's
    machine at an operating point P_m0 as the fourth-order model that plays it
    (``RecordOnFile.fourth_order``: its X', T'_0 seen through its dampers), the model the
    identified parameters it is compared with belong to.

    The field's base comes from the no-load tests seen so far: an event played before one was
    seen (an on-line test first in the day) is played again when the base it gives changes, and
    its verdict revised (said in its notes), so that at the end every verdict is validate's on
    the same windows (for the ``KEPT_RECENT`` latest events; every no-load test's is kept, up to
    ``KEPT_NO_LOAD``, for the base)."""

    describe: str
    play: Player
    to_scenario: Callable[[EventWindow], ScenarioData]
    parameters_at: Callable[[float], GeneratorParameters]
    settings: RecordCheckSettings = field(default_factory=RecordCheckSettings)
    on_base: FieldBase = _unchanged
    verdicts: list[EventVerdict] = field(default_factory=list)
    drift: list[RecordDrift] = field(default_factory=list)
    p_m0: float = math.nan  # the last event's operating point (the record's D in phid's form there)
    _scenarios: dict[str, tuple[ScenarioData, EventWindow]] = field(default_factory=dict, repr=False)
    _base: tuple[str, ...] = ()  # what the field's base was said to be when the verdicts were given

    def check(self, window: EventWindow, f_nominal_hz: float) -> list[EventVerdict]:
        """The window played into the record: its verdict, first, and those of earlier events
        played again because the field's base changed; empty for a window no check can use."""
        if not window.usable or not len(window.t_ns):
            return []
        scenario = self.to_scenario(window)
        if not scenario.has(*PLAYED_IN):
            return []  # phid validate refuses such a recording: the play-in needs V_t, P and Q
        self._scenarios[window.event.event_id] = (scenario, window)
        self._forget()
        names = list(self._scenarios)
        based, notes = self.on_base([sc for sc, _ in self._scenarios.values()])
        by_event = dict(zip(names, based, strict=True))
        changed = tuple(notes) != self._base
        self._base = tuple(notes)
        verdict = self._verdict(by_event[window.event.event_id], window, f_nominal_hz, notes)
        if scenario.has("p_e"):
            self.p_m0 = float(scenario["p_e"][scenario.pre_slice()].mean())
        revised = []
        if changed:
            for i, old in enumerate(self.verdicts):
                if old.event_id in by_event:
                    again = self._verdict(by_event[old.event_id], self._scenarios[old.event_id][1], f_nominal_hz, notes)
                    again.notes.append("played again: the field's base changed with a no-load test seen since")
                    again.level, again.status, again.drifting = old.level, old.status, old.drifting
                    self.verdicts[i] = again
                    revised.append(again)
        if verdict.checked:
            self.verdicts.append(verdict)
            verdict.level, verdict.status = self.status()
            verdict.drifting = [d.text() for d in self.drift]
        return ([verdict] if verdict.checked else []) + revised

    def _forget(self) -> None:
        """Keep every no-load test (up to ``KEPT_NO_LOAD``) and the ``KEPT_RECENT`` latest others."""
        no_load = [k for k, (sc, _) in self._scenarios.items() if at_no_load(sc)]
        others = [k for k in self._scenarios if k not in set(no_load)]
        for k in no_load[:-KEPT_NO_LOAD] + others[:-KEPT_RECENT]:
            del self._scenarios[k]

    def _verdict(
        self, scenario: ScenarioData, window: EventWindow, f_nominal_hz: float, base: list[str]
    ) -> EventVerdict:
        result = self.play([scenario], f_nominal_hz)
        [played] = result.scenarios
        verdict = EventVerdict(
            window.event.event_id,
            window.event.kind,
            int(window.t_ns[-1]),
            result.unit,
            list(played.checks),
            list(dict.fromkeys([*base, *result.notes, *played.notes])),
        )
        if not verdict.passed and sum(v.overlay is not None for v in self.verdicts) < MAX_OVERLAYS:
            verdict.overlay = played
        return verdict

    def recent(self) -> list[EventVerdict]:
        return self.verdicts[-self.settings.window :]

    def status(self) -> tuple[Level, str]:
        """The record's diagnostic level and message, naming the channel and the event."""
        recent = self.recent()
        if not recent:
            return OK, f"{self.describe}: no event checked yet"
        failing = [v for v in recent if not v.passed]
        limit = self.settings.error_bands
        beyond = [(v, c) for v in recent for c in v.failed() if c.band > 0 and c.max_error > limit * c.band]
        drift = f"; drifting from the record: {'; '.join(d.text() for d in self.drift)}" if self.drift else ""
        if beyond:
            v, c = max(beyond, key=lambda vc: vc[1].max_error / vc[1].band)
            return ERROR, (
                f"{self.describe}: {c.standard} {_channel(c)} off by {c.max_error:.3g} pu "
                f"({c.max_error / c.band:.1f} x its band {c.band:.3g}) at {v.event_id}{drift}"
            )
        if len(failing) >= self.settings.warn_events:
            named = ", ".join(f"{v.event_id} ({', '.join(_channel(c) for c in v.failed())})" for v in failing)
            return WARN, (
                f"{self.describe}: failed a check on {len(failing)} of the last {len(recent)} events: {named}{drift}"
            )
        level = WARN if self.drift else OK
        passed = sum(v.passed for v in recent)
        return level, f"{self.describe}: passed {passed} of the last {len(recent)} events{drift}"

    def compare(self, estimates: Mapping[str, Estimate]) -> list[RecordDrift]:
        """The identified parameters (identifiable, with a std) that differ from the record's by
        more than ``drift_sigmas`` stds; kept as the current drift."""
        if not math.isfinite(self.p_m0):
            return self.drift
        record = self.parameters_at(self.p_m0).as_dict()
        out = []
        for n in PARAMETER_NAMES:
            e = estimates.get(n)
            if e is None or not e.identifiable or not (math.isfinite(e.value) and math.isfinite(e.std) and e.std > 0):
                continue
            value, on_file = e.value, record[n]
            if n == "D":
                # in the record's own terms: PSS/E's torque-form D is phid's less P_m0 and never
                # negative, so a D below P_m0 is written 0 and is not the record's error
                value, on_file = max(0.0, value - self.p_m0), on_file - self.p_m0
            d = RecordDrift(n, on_file, value, e.std)
            if d.sigmas > self.settings.drift_sigmas:
                out.append(d)
        self.drift = out
        return out

    def diagnostic_values(self) -> list[tuple[str, str]]:
        """The status's key values: the last events' verdicts and the drifting parameters."""
        recent = self.recent()
        values = [
            ("events_checked", str(len(self.verdicts))),
            ("failed_of_last", f"{sum(not v.passed for v in recent)} of {len(recent)}"),
        ]
        values += [(f"drift {d.name}", d.text()) for d in self.drift]
        return values


def _channel(c: ChannelCheck) -> str:
    return CHANNELS[c.channel][1]
