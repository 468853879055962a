"""Event-to-scenario preparation: windows of aligned signals around one disturbance.

A :class:`ScenarioData` holds its window's :class:`~phid_ros.model.channels.Frame` (the
ten channels on a uniform grid, their stamps and period), the sample indices of the
disturbance (and of fault clearing), and V_d, V_q from V_t and the internal angle
delta - theta_t. :func:`classify` names the kind of disturbance
from the signals when the input does not say (fault: V_t below 0.3 of pre-fault,
the paper's detector; torque step: a step in P_m; voltage step: a sustained V_t
change without a fault).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import PhidError
from phid_ros.io.topics import RECORDER_CHANNELS
from phid_ros.model.channels import CHANNELS, SAME_PERIOD, Frame  # the one channel table, shared by every layer
from phid_ros.model.conventions import NS, seconds_to_ns, terminal_to_dq
from phid_ros.numerics import interpolant

Array = NDArray[np.float64]
KINDS = ("torque_step", "voltage_step", "fault", "field_step")

FAULT_VOLTAGE_RATIO = 0.3  # paper, section 3.2.2: V_t < 0.3 V_pf
# a fault is the collapse of a running machine's terminal voltage: below half its rating there
# is none to collapse (a de-excited machine, a voltage measurement lost), and the noise about
# zero crosses any ratio of it (the Mostar day: 100 "faults" after a VT was lost at no load)
MIN_PREFAULT_VOLTAGE = 0.5
MIN_TORQUE_STEP = 0.02  # pu of P_m
MIN_VOLTAGE_STEP = 0.02  # pu of V_t
MIN_FIELD_STEP = 0.02  # pu of V_f (about 1 % of a loaded machine's field voltage)
STEADY_FRACTION = 0.2  # paper: steady state from the final 20 % of a scenario
# A labelled step is located without the thresholds above (MOD-026/027 staged tests are
# small on purpose: a 2 % AVR reference step, a small load change), but it must stand this
# many standard deviations of a step estimate out of the signal's own noise.
STEP_NOISE_SIGMAS = 8.0
# a step's onset: the first sample further from the level before it than this many noise
# deviations (of a sample-to-sample difference) and this share of the step
ONSET_SIGMAS = 4.0
ONSET_SHARE = 0.1


@dataclass(frozen=True)
class StepThresholds:
    """The smallest P_m and V_t steps taken for a disturbance when nothing says one happened."""

    torque_step: float = MIN_TORQUE_STEP
    voltage_step: float = MIN_VOLTAGE_STEP
    field_step: float = MIN_FIELD_STEP


DEFAULT_THRESHOLDS = StepThresholds()


T = TypeVar("T")


class ScenarioError(PhidError):
    """A scenario window cannot be prepared (too short, NaN, no disturbance found)."""


@dataclass
class ScenarioData:
    name: str
    kind: str
    role: str
    generator_damping: bool
    frame: Frame  # the window's samples, viewed, not copied
    k_event: int
    k_clear: int | None = None
    notes: list[str] = field(default_factory=list)
    extra_switching: list[int] = field(default_factory=list)  # further steps inside a long window
    # the window the samples were measured over (a one-cycle DFT's phasors, a PMU's filter): a
    # switching instant is smeared over it, so stage 3 leaves it out around each switch
    measurement_window_s: float = 0.0
    # channels the recording did not carry (NaN throughout): the stages that need one leave it
    # out and say so (phid_ros.ident.determinable)
    absent: frozenset[str] = frozenset()
    # where the post-event steady state begins, when the window's own span says (an event cut out of
    # a test file that holds several: its plateau ends where the next event's window starts); None:
    # the paper's final fifth
    steady_start: int | None = None
    # who held the field: "avr", "manual" (a field-current regulator: the AVR not in the loop), or ""
    regulator: str = ""
    # a recorder's own channels on the frame's samples (the field current, the regulator's and the
    # stabiliser's outputs: :data:`phid_ros.io.topics.RECORDER_STREAMS`), where it kept them
    recorded: dict[str, Array] = field(default_factory=dict)
    # the test sheet's reference step, pu, unsigned (the event's own direction signs it), where it says
    reference_step: float | None = None
    # the event's time in the test file it was cut from (s), where it was cut from a file's events
    # (:func:`phid_ros.stream.scenarios.scenarios_from_recording`); None otherwise
    file_time_s: float | None = None
    # the signals say another kind than its label, and the label was kept: what was said of it
    # (a problem of the identification, said once; not an identification problem of its own)
    label_kept: str = ""
    # what the stages derive from this scenario alone, kept for the next identification that reads
    # it (a recalibration every few minutes re-reads the same stored windows); not an init field,
    # so a scenario made from this one (dataclasses.replace, with_frame) starts without it
    _derived: dict[tuple[Any, ...], Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.v_d, self.v_q = terminal_to_dq(self["v_t"], self["delta"], self["theta_t"])
        if not 0 < self.k_event < self.n:
            raise ScenarioError(
                f"scenario {self.name}: event sample {self.k_event} outside the window of {self.n} samples"
            )

    def derived(self, key: tuple[Any, ...], make: Callable[[], T]) -> T:
        """``make()``, computed once per scenario and ``key`` (the function's name and every
        argument besides the scenario). Only for results read, never written, by the caller; the
        scenario's own fields that ``make`` reads (its switching) are part of the key."""
        key = (*key, self.k_event, self.k_clear, tuple(self.extra_switching), self.generator_damping, self.kind)
        if key not in self._derived:
            self._derived[key] = make()
        return self._derived[key]

    def has(self, *channels: str) -> bool:
        """Whether the recording carried every one of ``channels`` (v_d, v_q: V_t, theta_t and delta)."""
        for c in channels:
            if c in RECORDER_CHANNELS:
                if c not in self.recorded or not np.isfinite(self.recorded[c]).all():
                    return False
                continue
            needs = ("v_t", "theta_t", "delta") if c in ("v_d", "v_q") else (c,)
            if any(n in self.absent for n in needs):
                return False
        return True

    @property
    def n(self) -> int:
        return len(self.frame)

    @property
    def dt(self) -> float:
        """The sample period in s."""
        return self.frame.period_ns / NS

    @property
    def start_ns(self) -> int:
        """The stamp of the window's first sample."""
        return int(self.frame.t_ns[0])

    @property
    def t(self) -> Array:
        return np.arange(self.n, dtype=np.float64) * self.dt

    @property
    def switching(self) -> list[int]:
        """Samples at which an input or the network switches (event, clearing)."""
        out = [self.k_event] + ([self.k_clear] if self.k_clear is not None else [])
        return sorted(set(out + [k for k in self.extra_switching if 0 < k < self.n]))

    def steady_slice(self) -> slice:
        if self.steady_start is not None:
            return slice(self.steady_start, self.n)
        return slice(int(round(self.n * (1.0 - STEADY_FRACTION))), self.n)

    def pre_slice(self) -> slice:
        return slice(0, self.k_event)

    def __getitem__(self, name: str) -> Array:
        if name == "v_d":
            return self.v_d
        if name == "v_q":
            return self.v_q
        if name in RECORDER_CHANNELS:
            return self.recorded[name]
        return self.frame.channel(name)

    def with_frame(self, frame: Frame) -> ScenarioData:
        """The scenario over another frame of as many samples (restamped, or channels derived)."""
        return ScenarioData(
            self.name,
            self.kind,
            self.role,
            self.generator_damping,
            frame,
            self.k_event,
            self.k_clear,
            list(self.notes),
            list(self.extra_switching),
            self.measurement_window_s,
            self.absent,
            self.steady_start,
            self.regulator,
            self.recorded,
            self.reference_step,
            self.file_time_s,
        )

    def rows(self, a: int, b: int) -> ScenarioData:
        """The scenario cut to samples a to b (exclusive; the event must lie inside), as views."""
        return ScenarioData(
            self.name,
            self.kind,
            self.role,
            self.generator_damping,
            self.frame.rows(a, b),
            self.k_event - a,
            None if self.k_clear is None else self.k_clear - a,
            list(self.notes),
            [k - a for k in self.extra_switching if a < k < b],
            self.measurement_window_s,
            self.absent,
            None if self.steady_start is None else min(max(self.steady_start - a, 0), b - a - 1),
            self.regulator,
            {c: x[a:b] for c, x in self.recorded.items()},
            self.reference_step,
            self.file_time_s,
        )


def file_of(s: ScenarioData | str) -> str:
    """The test file a scenario (or a scenario's name) was cut from: an event's scenario is named
    ``FILE@13.3s``."""
    return (s if isinstance(s, str) else s.name).rsplit("@", 1)[0]


def _largest_step(x: Array, span: int) -> tuple[int, float]:
    """Sample and size of the largest mean shift between ``span`` samples before and after."""
    c = np.concatenate(([0.0], np.cumsum(x)))
    k = np.arange(span, len(x) - span)
    if k.size == 0:
        return 0, 0.0
    after = (c[k + span] - c[k]) / span
    before = (c[k] - c[k - span]) / span
    d = after - before
    i = int(np.argmax(np.abs(d)))
    return int(k[i]), float(d[i])


def classify(
    signals: Mapping[str, Array],
    dt: float,
    pre_seconds: float = 0.5,
    thresholds: StepThresholds = DEFAULT_THRESHOLDS,
) -> tuple[str, int, int | None, str]:
    """(kind, event sample, clearing sample or None, reason) from the signals alone."""
    v = np.asarray(signals["v_t"], float)
    n_pre = max(1, int(round(pre_seconds / dt)))
    v_pf = float(np.median(v[:n_pre]))
    below = np.flatnonzero(v < FAULT_VOLTAGE_RATIO * v_pf)
    if below.size:
        k_ev = int(below[0])
        after = np.flatnonzero(v[k_ev:] >= FAULT_VOLTAGE_RATIO * v_pf)
        k_cl = k_ev + int(after[0]) if after.size else None
        return "fault", k_ev, k_cl, f"V_t fell to {v.min():.3f} pu < {FAULT_VOLTAGE_RATIO} x {v_pf:.3f} pu"
    span = max(5, int(round(0.2 / dt)))
    k_pm, d_pm = _largest_step(np.asarray(signals["p_m"], float), span)
    if abs(d_pm) >= thresholds.torque_step:
        return (
            "torque_step",
            _refine(np.asarray(signals["p_m"], float), k_pm, span),
            None,
            f"P_m stepped {d_pm:+.3f} pu",
        )
    # an exciter/AVR reference step moves V_f at once and V_t only through the field's time
    # constant: it is looked for before V_t's own steps
    k_f, d_f = _largest_step(np.asarray(signals["v_f"], float), span)
    if abs(d_f) >= thresholds.field_step:
        return "field_step", _refine(np.asarray(signals["v_f"], float), k_f, span), None, f"V_f stepped {d_f:+.3f} pu"
    k_v, d_v = _largest_step(v, span)
    if abs(d_v) >= thresholds.voltage_step:
        return "voltage_step", _refine(v, k_v, span), None, f"V_t stepped {d_v:+.3f} pu"
    raise ScenarioError(
        f"no disturbance found (no fault, no P_m step >= {thresholds.torque_step:g} pu, "
        f"no V_f step >= {thresholds.field_step:g} pu, no V_t step >= {thresholds.voltage_step:g} pu)"
    )


FIRST_RESPONSE_S = (0.02, 0.15)  # the response right after a step, before the field's flux moves


def from_the_field(signals: Mapping[str, Array], dt: float, k: int) -> str | None:
    """Why a V_t step at sample ``k`` came from the machine's field (an AVR reference or a field
    step), or None. A step of the network's voltage makes a loaded machine absorb reactive power
    as V_t rises (Q falls); raising its own field makes it deliver more (Q rises): the sign of
    dQ/dV_t right after the step tells them apart (FIRST_RESPONSE_S, while the field's flux still
    holds the EMF behind X'_d: later a weak machine's Q can follow a network step), where both
    moved clearly against a second of the signals' own noise before the event."""
    v, q = np.asarray(signals["v_t"], float), np.asarray(signals["q_e"], float)
    if not (np.isfinite(v).all() and np.isfinite(q).all()):
        return None
    one = max(2, int(round(1.0 / dt)))
    lo, hi = k + max(1, int(round(FIRST_RESPONSE_S[0] / dt))), k + max(2, int(round(FIRST_RESPONSE_S[1] / dt)))
    if k - one < 0 or hi > len(v):
        return None
    dv = float(np.mean(v[lo:hi]) - np.mean(v[k - one : k]))
    dq = float(np.mean(q[lo:hi]) - np.mean(q[k - one : k]))
    m = hi - lo
    noise_v = float(np.std(np.diff(v[k - one : k]))) * STEP_NOISE_SIGMAS / math.sqrt(m)
    noise_q = float(np.std(np.diff(q[k - one : k]))) * STEP_NOISE_SIGMAS / math.sqrt(m)
    if abs(dv) > max(noise_v, 1e-3) and abs(dq) > max(noise_q, 1e-3) and dv * dq > 0:
        return (
            f"Q moved with V_t in the first {FIRST_RESPONSE_S[1]:g} s ({dq:+.3f} pu for {dv:+.4f} pu): at a "
            "network step they move apart (the field's flux holds the EMF behind X'_d)"
        )
    return None


STEP_SIGNAL = {"torque_step": "p_m", "voltage_step": "v_t", "field_step": "v_f"}


# where a labelled step shows when its own signal was not recorded (a PMU export has no P_m, a
# trend log may lack E_fd): the electrical response, located less sharply
STEP_FALLBACK = {"torque_step": "p_e", "field_step": "v_t"}


def locate_labelled_step(signals: Mapping[str, Array], dt: float, kind: str) -> tuple[int, str]:
    """The event sample of a step the input labelled, however small, if it stands out of the noise."""
    c = STEP_SIGNAL[kind]
    if not np.isfinite(signals[c]).any() and kind in STEP_FALLBACK:
        c = STEP_FALLBACK[kind]
    x = np.asarray(signals[c], float)
    span = max(5, int(round(0.2 / dt)))
    k, d = _largest_step(x, span)
    # noise from the first differences (robust to the step itself); a step estimate's std is sigma sqrt(2/span)
    sigma = float(np.median(np.abs(np.diff(x)))) / (0.6745 * math.sqrt(2.0))
    floor = STEP_NOISE_SIGMAS * sigma * math.sqrt(2.0 / span)
    if not abs(d) > floor:
        raise ScenarioError(
            f"labelled {kind} but no {c} step stands out of the noise (largest {d:+.4f} pu, "
            f"{STEP_NOISE_SIGMAS:g} sigma of a step estimate is {floor:.4f} pu)"
        )
    return _refine(x, k, span), f"located the labelled {kind}: {c} stepped {d:+.4f} pu"


def _refine(x: Array, k: int, span: int) -> int:
    """The step's onset near ``k``: the first sample that left the level before it, found back
    from the first sample past half the step. The half-way sample alone is late by the rise: a
    regulator's output that falls in three samples was stepped two samples earlier, and at 30 pu/s
    one sample of 4.8 ms is 0.15 pu of E_fd (Mostar's AVR steps)."""
    a, b = max(1, k - span), min(len(x), k + span)
    before = x[max(0, a - span) : a]
    lo, hi = np.mean(before), np.mean(x[b : b + span]) if b < len(x) else x[-1]
    mid = 0.5 * (lo + hi)
    seg = x[a:b]
    crossed = np.flatnonzero((seg - mid) * np.sign(hi - lo) >= 0)
    if not crossed.size:
        return k
    j = a + int(crossed[0])
    noise = float(np.median(np.abs(np.diff(before)))) / 0.6745 if before.size > 2 else 0.0
    band = max(ONSET_SIGMAS * noise, ONSET_SHARE * abs(hi - lo))
    while j > a and (x[j - 1] - lo) * np.sign(hi - lo) > band:
        j -= 1
    return j


def _absent_channels(name: str, frame: Frame) -> frozenset[str]:
    """The channels not recorded (NaN throughout) in a window long enough to identify from;
    refused where a channel is partly NaN or one every identification needs is absent."""
    n, dt = len(frame), frame.period_ns / NS
    if n < int(2.0 / dt):
        raise ScenarioError(f"scenario {name}: window of {n * dt:.2f} s is too short (needs >= 2 s)")
    bad = ~np.isfinite(frame.values)
    none = bad.all(axis=0)
    if (bad.any(axis=0) & ~none).any():
        i = int(np.flatnonzero(bad.any(axis=0) & ~none)[0])
        rows = np.flatnonzero(bad[:, i])
        raise ScenarioError(
            f"scenario {name}: channel {CHANNELS[i]} has {rows.size} NaN/Inf sample(s), "
            f"first at t = {rows[0] * dt:.3f} s"
        )
    absent = frozenset(CHANNELS[i] for i in np.flatnonzero(none))
    missing = [c for c in ("v_t", "p_e", "q_e") if c in absent]
    if missing:
        raise ScenarioError(f"scenario {name}: no data on {', '.join(missing)}: every identification needs them")
    return absent


def _labelled_step(
    name: str, sig: Mapping[str, Array], dt: float, kind: str, thresholds: StepThresholds, notes: list[str]
) -> int | None:
    """Where a step the input labels ``kind`` is: as classified where the signals say the same
    kind, located however small where they show no step (a staged test's under the thresholds);
    None where they say another kind (the caller classifies and says so). Appends the reason."""
    try:
        found, k_ev, _k_cl, reason = classify(sig, dt, thresholds=thresholds)
    except ScenarioError:
        found = ""
    if found == kind:
        notes.append(f"classified as {found}: {reason}")
        return k_ev
    if found:
        return None
    try:
        k_event, reason = locate_labelled_step(sig, dt, kind)
    except ScenarioError as exc:
        raise ScenarioError(f"scenario {name}: {exc}") from None
    notes.append(reason)
    return k_event


def make_scenario(
    name: str,
    frame: Frame,
    *,
    kind: str = "unknown",
    role: str = "identify",
    generator_damping: bool = True,
    k_event: int | None = None,
    k_clear: int | None = None,
    thresholds: StepThresholds = DEFAULT_THRESHOLDS,
    measurement_window_s: float = 0.0,
    regulator: str = "",
    recorded: Mapping[str, Array] | None = None,
    reference_step: float | None = None,
) -> ScenarioData:
    """Check a window and build its :class:`ScenarioData`; classify it where the input does not say.
    ``recorded``: a recorder's own channels on the frame's samples (kept where any is finite).

    A step the input labels (manifest ``kind``) is located however small it is; only an
    unlabelled window must show a step above ``thresholds`` to count as a disturbance.
    """
    n, dt = len(frame), frame.period_ns / NS
    absent = _absent_channels(name, frame)
    sig = frame.columns()
    notes: list[str] = [f"not recorded: {', '.join(c for c in CHANNELS if c in absent)}"] if absent else []
    label_kept = ""
    if kind in STEP_SIGNAL and (k_event is None or k_event <= 0):
        k_event = _labelled_step(name, sig, dt, kind, thresholds, notes)
    if kind == "unknown" or k_event is None or k_event <= 0:
        try:
            found, k_ev, k_cl, reason = classify(sig, dt, thresholds=thresholds)
        except ScenarioError as exc:
            raise ScenarioError(f"scenario {name}: {exc}") from None
        if kind not in ("unknown", found):
            label_kept = f"labelled {kind} but the signals say {found} ({reason}); kept the label"
            notes.append(label_kept)
        else:
            kind = found
            notes.append(f"classified as {found}: {reason}")
        if k_event is None or k_event <= 0:
            k_event, k_clear = k_ev, (k_cl if kind == "fault" else None)
    if kind not in KINDS:
        raise ScenarioError(f"scenario {name}: kind {kind!r} not one of {KINDS}")
    if kind == "voltage_step" and k_event is not None and (why := from_the_field(sig, dt, int(k_event))):
        kind = "field_step"
        notes.append(f"labelled voltage_step, taken as field_step: {why}")
    if kind == "fault" and k_clear is None:
        _, _, k_clear, _ = classify(sig, dt)
    return ScenarioData(
        name=name,
        kind=kind,
        role=role,
        generator_damping=generator_damping,
        frame=frame,
        k_event=int(k_event),
        k_clear=None if k_clear is None else int(k_clear),
        notes=notes,
        measurement_window_s=measurement_window_s,
        absent=absent,
        regulator=regulator,
        recorded={c: x for c, x in (recorded or {}).items() if len(x) == n and np.isfinite(x).any()},
        reference_step=reference_step,
        label_kept=label_kept,
    )


def scenario_from_simulation(run: Any, signals: Mapping[str, Array]) -> ScenarioData:
    """A simulated run's analysis window (``run``: a ``sim.runner.ScenarioRun``, duck-typed so
    identification does not import the simulator), labelled with the scenario's known kind and
    event samples; ``signals`` is its truth or a measured (noisy) draw."""
    sc = run.scenario
    n = run.n_analysis
    dt = float(run.t[1] - run.t[0])
    return make_scenario(
        sc.name,
        Frame.of_columns({k: v[:n] for k, v in signals.items()}, seconds_to_ns(dt)),
        kind=sc.kind,
        role=sc.role,
        generator_damping=sc.generator_damping,
        k_event=int(round(sc.t_event / dt)),
        k_clear=None if sc.t_clear is None else int(round(sc.t_clear / dt)),
    )


def _moving_step(x: Array, span: int) -> Array:
    """Mean of the next ``span`` samples minus mean of the previous ``span``, at every sample."""
    n = len(x)
    out = np.zeros(n)  # zero where either side has fewer than ``span`` samples
    if n >= 2 * span:
        c = np.concatenate(([0.0], np.cumsum(x)))
        # slices, not gathers through index arrays (the detector runs this twice per half second)
        mid = c[span : n - span + 1]
        out[span : n - span + 1] = (c[2 * span :] - mid) / span - (mid - c[: n - 2 * span + 1]) / span
    return out


RUN_SPLIT_SHARE = 0.2  # a run of step candidates is cut where the step falls below this share of its peak


def run_peaks(d: Array, run: np.ndarray, span: int) -> list[int]:
    """The events in one run of samples whose moving step ``d`` passes its threshold: the run cut
    where ``d`` falls below RUN_SPLIT_SHARE of the run's peak, one event at each part's peak. A
    field forced through a build-up from standstill stays just above the threshold for seconds:
    taken whole, the run's peak was the forcing's end (U_f from 205 V back to 63 V at Zakucac, 9 s
    after the field went on), and the build-up's window began there. Parts of one disturbance are
    joined again as its own transient (:func:`phid_ros.ident.file_events.events_of_file`)."""
    level = RUN_SPLIT_SHARE * float(np.max(d[run]))
    strong = run[d[run] >= level]
    parts = np.split(strong, np.flatnonzero(np.diff(strong) > span) + 1)
    return [int(p[np.argmax(d[p])]) for p in parts]


def find_events(
    signals: Mapping[str, Array],
    dt: float,
    *,
    quiet_s: float = 2.0,
    thresholds: StepThresholds = DEFAULT_THRESHOLDS,
) -> list[tuple[str, int, int | None]]:
    """Disturbances in a continuous recording: (kind, event sample, clearing sample or None).

    Faults first (V_t below 0.3 of its mean over the preceding second, that mean at least
    MIN_PREFAULT_VOLTAGE), then
    steps in P_m, then steps in V_t; a lower-priority detection within
    ``quiet_s`` of another event is the same disturbance seen in another signal.
    """
    v = np.asarray(signals["v_t"], float)
    n = len(v)
    span_pf = max(1, int(round(1.0 / dt)))
    c = np.concatenate(([0.0], np.cumsum(v)))
    v_pf = np.empty(n)  # the mean over the preceding second (fewer samples at the start)
    head = min(span_pf, n)
    v_pf[:head] = c[:head] / np.maximum(np.arange(head), 1)
    v_pf[head:] = (c[head:n] - c[: n - head]) / span_pf
    v_pf[0] = v[0]
    events: list[tuple[str, int, int | None]] = []
    below = (v < FAULT_VOLTAGE_RATIO * v_pf) & (v_pf >= MIN_PREFAULT_VOLTAGE)
    below[:span_pf] = False
    edges = np.diff(below.astype(np.int8), prepend=0)
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1)
    for s in starts:
        after = stops[stops > s]
        events.append(("fault", int(s), int(after[0]) if after.size else None))
    quiet = int(round(quiet_s / dt))

    def busy(k0: int) -> bool:
        return any(abs(k0 - e[1]) < quiet or (e[2] is not None and abs(k0 - e[2]) < quiet) for e in events)

    span = max(5, int(round(0.2 / dt)))
    steps = [("torque_step", signals["p_m"], thresholds.torque_step)]
    if "v_f" in signals:  # a detector that does not watch the excitation stream does not see field steps
        steps.append(("field_step", signals["v_f"], thresholds.field_step))
    steps.append(("voltage_step", v, thresholds.voltage_step))
    for kind, x, thr in steps:
        d = np.abs(_moving_step(np.asarray(x, float), span))
        cand = np.flatnonzero(d >= thr)
        if cand.size == 0:
            continue
        # one event per run of candidate samples: its peak, a run cut where the step falls away
        groups = np.split(cand, np.flatnonzero(np.diff(cand) > span) + 1)
        for k_peak in (k for g in groups for k in run_peaks(d, g, span)):
            if not busy(k_peak):
                events.append((kind, _refine(np.asarray(x, float), k_peak, span), None))
    events.sort(key=lambda e: e[1])
    return events


def resampled(s: ScenarioData, period_ns: int) -> ScenarioData:
    """The scenario on a coarser grid: each channel low-passed forward and backward (4th-order
    Butterworth at 0.8 of the new Nyquist frequency, no delay) and interpolated; its event,
    clearing and switching samples moved to the new grid."""
    from scipy.signal import butter, sosfiltfilt

    if abs(period_ns - s.frame.period_ns) <= SAME_PERIOD * period_ns:  # one rate, clocks a few ns apart
        t_ns = int(s.frame.t_ns[0]) + np.arange(s.n, dtype=np.int64) * period_ns
        return s.with_frame(Frame(t_ns, s.frame.values, period_ns))
    old_dt, new_dt = s.dt, period_ns / NS
    t_old = np.arange(s.n) * old_dt
    t_new = np.arange(0.0, t_old[-1] + 0.5 * old_dt, new_dt)
    sos = butter(4, 0.8 * (0.5 / new_dt) / (0.5 / old_dt), output="sos")
    values = np.empty((len(t_new), s.frame.values.shape[1]), order="F")
    for i in range(values.shape[1]):
        x = s.frame.values[:, i]
        values[:, i] = interpolant(t_old, sosfiltfilt(sos, x) if np.isfinite(x).all() else x)(t_new)

    def at(k: int) -> int:
        return int(round(k * old_dt / new_dt))

    recorded = {
        c: interpolant(t_old, sosfiltfilt(sos, x) if np.isfinite(x).all() else x)(t_new) for c, x in s.recorded.items()
    }

    out = ScenarioData(
        s.name,
        s.kind,
        s.role,
        s.generator_damping,
        Frame(int(s.frame.t_ns[0]) + np.arange(len(t_new), dtype=np.int64) * period_ns, values, period_ns),
        at(s.k_event),
        None if s.k_clear is None else at(s.k_clear),
        [*s.notes, f"resampled from {1 / old_dt:g} to {1 / new_dt:g} samples/s (zero-phase low-pass, linear)"],
        [at(k) for k in s.extra_switching],
        s.measurement_window_s,
        s.absent,
        None if s.steady_start is None else at(s.steady_start),
        s.regulator,
        recorded,
        s.reference_step,
        s.file_time_s,
    )
    return out


def on_one_grid(scenarios: list[ScenarioData]) -> tuple[list[ScenarioData], list[str]]:
    """Scenarios of several recorders on the coarsest sample period among them (stages 1 and 3
    read one period), with a note per recording rate changed."""
    periods = sorted({s.frame.period_ns for s in scenarios})
    if len(periods) <= 1:
        return scenarios, []
    target = periods[-1]
    if periods[0] >= (1 - SAME_PERIOD) * target:
        return [resampled(s, target) for s in scenarios], []
    moved = [s.name for s in scenarios if s.frame.period_ns < (1 - SAME_PERIOD) * target]
    note = (
        f"{len(moved)} scenario(s) resampled to the coarsest rate among the recordings, "
        f"{NS / target:g} samples/s: {', '.join(moved[:4])}{' ...' if len(moved) > 4 else ''}"
    )
    return [resampled(s, target) for s in scenarios], [note]
