"""Recalibration policy and worker: the three-stage identification off the ingestion path.

The policy decides *when* (enough usable events of the kinds the stages need,
at least ``min_interval_s`` of stream time since the last run, or on demand)
and *with what* (the latest N events per kind). The worker runs the
identification in one background thread, so ingestion never waits; requests that
arrive while it runs are coalesced into one more run. A failed run, an
incomplete or physically invalid set, or an implausible jump from the last good
set keeps the last good parameters, with the reason in the outcome. Before any set is in force,
an incomplete run's determined parameters are published on their own (a partial set: a plant's
recorder without the rotor's channels determines some parameters, never all eight), the others
withheld by name.
"""

from __future__ import annotations

import math
import re
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

from phid_ros.controls.fit import ControlFit
from phid_ros.ident.pipeline import IdentificationResult, IdentifyOptions, identify
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import DEFAULT_THRESHOLDS, ScenarioData, ScenarioError, StepThresholds, make_scenario
from phid_ros.model.conventions import NS
from phid_ros.model.parameters import PARAMETER_NAMES, SYMBOLS, GeneratorParameters
from phid_ros.stream.detector import EventWindow
from phid_ros.stream.levels import Level
from phid_ros.stream.store import EventStore

ROTOR_CHANNELS = frozenset({"omega", "delta"})  # what a swing is read from (the encoder's stream)


@dataclass
class RecalibrationPolicy:
    latest_per_kind: int = 10
    # the stages' needs: a swing for stage 1 (a fault or a torque step) and a settled step for stage 2
    min_swing_events: int = 1
    min_step_events: int = 1
    min_interval_s: float = 300.0  # the paper recalibrates in batches over several minutes of events
    max_relative_jump: float = 0.5  # a parameter moving more than this in one run is implausible ...
    jump_sigmas: float = 4.0  # ... if the move also exceeds this many combined standard deviations

    # channels the recorder never carries: without the rotor's speed and angle no swing determines
    # H and D (the routes say so), and a run is not held back waiting for a swing event
    not_recorded: frozenset[str] = frozenset()

    def ready(self, counts: dict[str, int]) -> tuple[bool, str]:
        swings = counts.get("fault", 0) + counts.get("torque_step", 0)
        steps = counts.get("torque_step", 0) + counts.get("voltage_step", 0) + counts.get("field_step", 0)
        if swings < self.min_swing_events and not ROTOR_CHANNELS <= self.not_recorded:
            return False, f"needs {self.min_swing_events} fault or torque-step event(s), has {swings}"
        if steps < self.min_step_events:
            return False, f"needs {self.min_step_events} torque- or voltage-step event(s), has {steps}"
        return True, "ready"


KEPT_LAST_GOOD = "kept last good set: "
INCOMPLETE = "incomplete result ("
PARTIAL = "partial set: "
WITHHELD_WHY = "not determined by these channels and events (phid identify on the same events says why, per parameter)"


_NAMES = re.compile(r"\b(" + "|".join(sorted(SYMBOLS, key=len, reverse=True)) + r")\b")


def in_symbols(text: str) -> str:
    """``text`` with each parameter's name (X_d_prime) in the paper's symbol (X'_d), for a reader."""
    return _NAMES.sub(lambda m: SYMBOLS[m.group(1)], text)


@dataclass
class RecalibrationOutcome:
    accepted: bool
    status: str
    parameters: GeneratorParameters | None  # the set in force after this run (last good if rejected)
    result: IdentificationResult | None
    event_ids: list[str]
    stream_time_ns: int
    seconds: float
    # with no set in force yet: the parameters this incomplete run determined (identified, with a
    # finite std), published on their own; the set in force stays None
    determined: dict[str, Estimate] = field(default_factory=dict)
    # the exciter, governor and stabiliser fitted on the same events (by kind: the fit, or why none),
    # as phid identify fits them beside the machine; empty when the deployment does not ask for them
    controls: dict[str, ControlFit | str] = field(default_factory=dict)
    failed: bool = False  # the run raised (its status says what): no result at all
    # what ``said`` tells a reader, kept as facts beside the published ``status``: why the set was
    # not adopted (before any published prefix), the parameters adopted but flagged, the windows skipped
    why: str = ""
    flagged: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)

    @property
    def level(self) -> Level:
        """The run's diagnostic level (diagnostic_updater's): OK where its set was adopted, ERROR
        where the run failed, WARN otherwise (the last good set kept, a partial set, too few events)."""
        return Level.OK if self.accepted else (Level.ERROR if self.failed else Level.WARN)

    def said(self) -> tuple[str, str]:
        """(outcome, why) in the words of what happened to the set in force, for a reader: the first
        run on too few events read as a failure ("rejected: ... did not run") when the pipeline was
        waiting for more; ``status`` keeps the published wording."""
        skipped = "; skipped: " + "; ".join(self.skipped) if self.skipped else ""
        if self.accepted:
            names = ", ".join(SYMBOLS.get(n, n) for n in self.flagged)
            return "adopted", (f"withheld as poorly identified: {names}" if names else "") + skipped
        if self.parameters is None and self.determined:
            names = ", ".join(SYMBOLS.get(n, n) for n in self.determined)
            return f"partial set published: {names}", in_symbols(self.why) + skipped
        if self.parameters is None:
            return "no set yet (the events so far do not determine every parameter)", self.why + skipped
        return "not adopted, the set in force kept", self.why + skipped


def determined_only(result: IdentificationResult) -> dict[str, Estimate]:
    """The parameters ``result`` identified with a finite value and std, in the contract's order:
    what a partial set publishes. A value flagged not identifiable, or without a std, is withheld."""
    est = result.estimates
    return {
        n: est[n]
        for n in PARAMETER_NAMES
        if n in est
        and est[n].identifiable
        and math.isfinite(est[n].value)
        and math.isfinite(est[n].std)
        and est[n].std > 0
    }


def scenario_from_window(
    w: EventWindow, *, thresholds: StepThresholds = DEFAULT_THRESHOLDS, measurement_window_s: float = 0.0
) -> ScenarioData:
    """An event window as the identification's scenario: the one conversion, for the worker and
    for ``phid identify`` on a recording without markers."""
    e = w.event
    # a labelled event is named as phid identify names a test file's events, FILE@when, so the
    # events of one file go together (the left-out check, the field circuit's per-file figures)
    name = f"{e.name}@{e.event_id.rsplit('@', 1)[1]}" if e.name else e.event_id
    k_ev = int((e.inception_ns - int(w.t_ns[0])) // w.period_ns)
    k_cl = int((e.clearing_ns - int(w.t_ns[0])) // w.period_ns) if e.clearing_ns else None
    made = make_scenario(
        name,
        w,
        kind=e.kind,
        role=e.role,
        generator_damping=e.generator_damping,
        k_event=k_ev,
        k_clear=k_cl,
        thresholds=thresholds,
        measurement_window_s=measurement_window_s,
        recorded=w.recorded,
        regulator=e.regulator,
        reference_step=e.reference_step,
    )
    if made.kind == "field_step":
        # its window holds the plateau before it (DetectorSettings.plateau_s): the steady state
        # after it is the second half of the span after it, as phid identify takes a test file's
        # (a fifth of the whole window began before a short test's step)
        made.steady_start = ((k_cl if k_cl is not None else k_ev) + made.n) // 2
    return made


def _window_key(w: EventWindow) -> tuple[object, ...]:
    """Everything :func:`scenario_from_window` reads but the samples: its event and label, the
    event's times, the window's span (a store replaces a window cut short with the complete one
    of the same event, and refuses one with other samples)."""
    e = w.event
    span = (int(w.t_ns[0]), int(w.t_ns[-1])) if len(w.t_ns) else (0, 0)
    return (
        e.event_id,
        e.name,
        e.kind,
        e.role,
        e.generator_damping,
        e.regulator,
        e.reference_step,
        e.inception_ns,
        e.clearing_ns,
        w.period_ns,
        len(w.t_ns),
        *span,
        tuple(sorted(w.recorded)),
    )


@dataclass
class Recalibrator:
    store: EventStore
    policy: RecalibrationPolicy = field(default_factory=RecalibrationPolicy)
    options: IdentifyOptions = field(default_factory=lambda: IdentifyOptions(baseline=False, validate=False))
    last_good: GeneratorParameters | None = None
    last_result: IdentificationResult | None = None
    runs: int = 0
    _executor: ThreadPoolExecutor = field(default_factory=lambda: ThreadPoolExecutor(1, "phid-recalibration"))
    _future: Future | None = None
    _dirty: bool = False
    _last_start_ns: int | None = None
    _unpolled: list[int] = field(default_factory=list)  # start times of runs not yet polled
    _done: list[RecalibrationOutcome] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    # each window's scenario (or why it is not one): the latest N a kind change by one or two between
    # runs, so most would be converted again (a tenth of a run's time); the worker's own
    _scenarios: dict[tuple[object, ...], ScenarioData | ScenarioError] = field(default_factory=dict)
    # the control systems fitted beside the machine at every run (phid identify fits all three; a
    # governor's fit on the catalogue's windows takes 14 s of a 17 s replay and the users
    # ask for the exciter and the stabiliser)
    controls: tuple[str, ...] = ("exciter", "stabiliser")
    # what the running recalibration is doing, for a progress line ("" while none runs), and who is
    # told when it changes (from the worker's thread): a run shorter than a progress line's poll
    # would otherwise never be shown, depending on the machine's speed
    activity: str = ""
    on_activity: Callable[[], None] | None = field(default=None, repr=False, compare=False)

    def _doing(self, activity: str) -> None:
        self.activity = activity
        if self.on_activity is not None:
            self.on_activity()

    def request(self, stream_time_ns: int, *, force: bool = False) -> str:
        """Ask for a run; returns what happened (started, coalesced, or why not)."""
        counts = self.store.counts()
        ok, why = self.policy.ready(counts)
        if not ok and (not force or not counts):
            return f"not ready: {why}" if counts else "not ready: the event store holds no usable event"
        if (
            not force
            and self._last_start_ns is not None
            and stream_time_ns - self._last_start_ns < self.policy.min_interval_s * NS
        ):
            self._dirty = True
            return "deferred: minimum interval since the last run"
        self._start(stream_time_ns)
        return "started"

    @property
    def open_since_ns(self) -> int | None:
        """Stream time at which the earliest run whose outcome has not been polled was started.

        A consumer that must behave as if recalibrations were instantaneous (the Hamiltonian)
        holds back its work from this stream time until the outcome is polled.
        """
        return min(self._unpolled) if self._unpolled else None

    def _start(self, stream_time_ns: int) -> None:
        # Runs start when stream time says so, never when the previous one happens to finish: a
        # run still going is waited for (at the policy's intervals a run is long done, except in
        # playback much faster than real time). So the sequence of runs, their inputs and their
        # outcomes are the same at any playback speed.
        self.join()
        windows = self.store.latest(n=self.policy.latest_per_kind)
        self._dirty = False
        self._last_start_ns = stream_time_ns
        self._unpolled.append(stream_time_ns)
        self._future = self._executor.submit(self._run, windows, stream_time_ns)

    def poll(self, stream_time_ns: int | None = None) -> list[RecalibrationOutcome]:
        """Finished runs since the last poll; starts a coalesced rerun when one is owed."""
        with self._lock:
            done, self._done = self._done, []
        for outcome in done:
            self._unpolled.remove(outcome.stream_time_ns)
        if self._dirty and stream_time_ns is not None:
            if self._last_start_ns is None or stream_time_ns - self._last_start_ns >= self.policy.min_interval_s * NS:
                self.request(stream_time_ns)
        return done

    def join(self) -> None:
        """Wait for the running job (if any) without taking its outcome: the next poll() gets it."""
        if self._future is not None:
            self._future.result()

    def wait(self) -> list[RecalibrationOutcome]:
        self.join()
        return self.poll()

    def finish(self, stream_time_ns: int) -> list[RecalibrationOutcome]:
        """End of input: run once more if events arrived since the last run, and wait."""
        out = self.wait()
        if self._dirty or self.runs == 0:
            ok, _ = self.policy.ready(self.store.counts())
            if ok:
                self._start(stream_time_ns)
                out += self.wait()
        return out

    def shutdown(self) -> None:
        self._executor.shutdown(wait=True)

    def _run(self, windows: list[EventWindow], stream_time_ns: int) -> None:
        t0 = time.perf_counter()
        ids = [w.event.event_id for w in windows]
        try:
            scenarios = []
            skipped = []
            for w in windows:
                made = self._scenario(w)
                if isinstance(made, ScenarioError):
                    skipped.append(str(made))
                else:
                    scenarios.append(made)
            # the next run's windows are among these and newer ones: the cache holds one run's
            self._scenarios = {k: self._scenarios[k] for k in map(_window_key, windows)}
            self._doing(f"recalibrating on {len(scenarios)} event window(s): the machine")
            result = identify(scenarios, self.options)
            if self.controls:
                fitting = " and the ".join(self.controls)
                self._doing(f"recalibrating on {len(scenarios)} event window(s): the {fitting}")
            controls = self._controls(scenarios, result) if self.controls else {}
            outcome = self._judge(result, ids, stream_time_ns, time.perf_counter() - t0)
            outcome.controls = controls
            if skipped:
                outcome.status += "; skipped: " + "; ".join(skipped)
                outcome.skipped = list(skipped)
        except Exception as exc:  # a failed run must never take the worker (or the node) down
            failure = f"recalibration failed: {type(exc).__name__}: {exc}"
            outcome = RecalibrationOutcome(
                False,
                failure,
                self.last_good,
                None,
                ids,
                stream_time_ns,
                time.perf_counter() - t0,
                failed=True,
                why=failure,
            )
        self._doing("")
        with self._lock:
            self.runs += 1
            self._done.append(outcome)

    def _controls(self, scenarios: list[ScenarioData], result: IdentificationResult) -> dict[str, ControlFit | str]:
        """The control systems asked for on the run's scenarios, as phid identify fits them
        (:func:`phid_ros.controls.identify.identify_machine_controls`); their failure is said, the
        machine's set stands."""
        from phid_ros.controls.identify import identify_machine_controls

        try:
            _, found, _ = identify_machine_controls(
                scenarios, result.route_details, self.options.constraints.saturation, kinds=self.controls
            )
            return found
        except Exception as exc:  # noqa: BLE001 - a control fit must not take the machine's outcome down
            return {"exciter": f"not identified: the fit failed ({type(exc).__name__}: {exc})"}

    def _scenario(self, w: EventWindow) -> ScenarioData | ScenarioError:
        """The window's scenario, made once: a stored window does not change (identification reads
        its scenarios and never writes them, so one serves every run it takes part in)."""
        key = _window_key(w)
        if key not in self._scenarios:
            try:
                self._scenarios[key] = scenario_from_window(w)
            except ScenarioError as exc:
                self._scenarios[key] = exc
        return self._scenarios[key]

    def _jumps(self, model: GeneratorParameters, result: IdentificationResult) -> dict[str, float]:
        """Parameters that moved implausibly: beyond the relative limit *and* the combined uncertainty.

        A parameter flagged as poorly identified in either set cannot anchor a rejection:
        an early, uncertain set must not block the better one that more events bring.
        """
        old, new = self.last_good.as_dict(), model.as_dict()  # type: ignore[union-attr]
        prev = self.last_result.estimates if self.last_result else {}
        out = {}
        for n in new:
            if not old[n]:
                continue
            rel = new[n] / old[n] - 1
            if abs(rel) <= self.policy.max_relative_jump:
                continue
            e_new, e_old = result.estimates.get(n), prev.get(n)
            if e_new is None or not e_new.identifiable or (e_old is not None and not e_old.identifiable):
                continue
            sigma = math.hypot(
                e_new.std if math.isfinite(e_new.std) else 0.0,
                e_old.std if e_old is not None and math.isfinite(e_old.std) else 0.0,
            )
            if abs(new[n] - old[n]) > self.policy.jump_sigmas * sigma:
                out[n] = rel
        return out

    def _judge(self, result: IdentificationResult, ids: list[str], now: int, seconds: float) -> RecalibrationOutcome:
        model = result.complete()
        if model is None:
            missing = [n for n, v in result.parameters.items() if not math.isfinite(v)]
            why = "; ".join(result.problems[:3]) or f"missing {missing}"
            determined = {} if self.last_good is not None else determined_only(result)
            if determined:
                held = result.constraints.fixed
                withheld = ", ".join(n for n in result.parameters if n not in determined and n not in held)
                why = f"withheld {withheld}: {WITHHELD_WHY}"
                if held:  # the user's datasheet values: neither determined here nor withheld
                    why += "; held: " + ", ".join(f"{n} = {v:g}" for n, v in held.items())
                status = f"{PARTIAL}{why}"
            else:
                status = f"{KEPT_LAST_GOOD}{INCOMPLETE}{why})"
            return RecalibrationOutcome(False, status, self.last_good, result, ids, now, seconds, determined, why=why)
        if self.last_good is not None:
            jumps = self._jumps(model, result)
            if jumps:
                text = ", ".join(f"{n} {100 * j:+.0f} %" for n, j in jumps.items())
                why = f"implausible jump ({text})"
                return RecalibrationOutcome(
                    False, f"{KEPT_LAST_GOOD}{why}", self.last_good, result, ids, now, seconds, why=why
                )
        self.last_good = model
        self.last_result = result
        flagged = [n for n, e in result.estimates.items() if not e.identifiable]
        status = "ok" if not flagged else f"ok; poorly identified: {', '.join(flagged)}"
        return RecalibrationOutcome(True, status, model, result, ids, now, seconds, flagged=flagged)
