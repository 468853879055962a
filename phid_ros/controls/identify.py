"""The exciter and the governor identified from the recordings, as MOD-026/027 ask for them.

Each control system is the map from its recorded inputs to its recorded output, in deviations
from the steady state before each event: the exciter from (V_ref - V_t) to E_fd, the governor
from the speed deviation and load-reference steps to P_m. A reference step (a field step, a
torque step) is one unknown size per scenario, fitted with the model. Every registered model of
the kind (:mod:`phid_ros.controls.models`) is fitted to the identification scenarios and judged
on the validation scenarios (held out); the one with the smallest held-out error is named, and
only if it explains clearly more than "no control action" (the output moving only with the
reference steps): the diagnosis's rule against naming what the data do not show.

Why the inputs are smoothed: the exciter's gain (~100) multiplies the PT's noise (0.002 pu)
into 0.2 pu on E_fd, which an output-error fit answers by lowering the gain; V_t and the speed
are low-passed forward and backward at 40 Hz (no lag). At 10 Hz the filter cut into the
exciter's own band: STEPS's SEXS gave T_E 0.0468 s for 0.05 (at 40 Hz 0.0495).

Limits: a model's output limits (SEXS's EMAX, ESST5B's VRMAX) are ``null`` unless the recorded
output reached them. Reached means a flat top: the recorded output sits within a few noise levels
of its extreme for at least ``MIN_FLAT_S``, having arrived there at speed or with the small-signal
fit wanting it further. Then the limit is fitted from there, the model played through its limits
(:meth:`ControlModel.limited`), every stepped scenario's reference a constant of that fit (the
response is no longer linear in it), and the faults join the exciter's fit: a fault drives the
field voltage to its ceiling, which is what pins it. A limit that fit leaves where it never binds
is dropped with it. Without a limit reached, faults stay out of the exciter's fit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.controls.models import (
    MODELS,
    ControlInputs,
    ControlModel,
    ControlParameter,
    LimitsError,
    OperatingLevels,
    of_kind,
)
from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.uncertainty import block_ids, cluster_robust_cov
from phid_ros.io.recording import STABILISER_ON
from phid_ros.numerics import lowpass2

Array = NDArray[np.float64]

INPUT_CUTOFF_HZ = 40.0
# the fit's sample rate: the inputs are smoothed below 40 Hz, so 250 samples a second keep what
# they carry (Nyquist 125 Hz), and the feedback models' fits (IEEET1: ~1600 evaluations of 15
# scenarios) take seconds, not a minute, on 1 kHz recordings
FIT_RATE_HZ = 250.0
KINDS = {
    # kind: (channels it needs, output channel, scenario kinds with a reference step, kinds fitted)
    "exciter": (("v_t", "v_f"), "v_f", ("field_step",), ("voltage_step", "torque_step", "field_step")),
    "governor": (("omega", "p_m"), "p_m", ("torque_step",), ("voltage_step", "torque_step", "field_step", "fault")),
    # a stabiliser from its recorded output (a recorder's own channel) against the electrical power
    "stabiliser": (("p_e", "v_s"), "v_s", (), ("voltage_step", "torque_step", "field_step")),
}
SWITCHED_OFF_S = 1.0  # a stabiliser output held at exactly one value this long: the stabiliser was off
EVENT_MARGIN_S = 0.05  # ... unless it starts to move this close to the event, or after: it answered the event
SIMPLEST_WITHIN = 1.05  # a model with more constants is chosen only where it errs 5 % less than a simpler one
MAX_EVALUATIONS = 200
SECOND_START = 0.15  # the second fit starts this share of each constant's range away from the first's end
# the refits of the profile check start at the optimum, one constant moved: a few steps settle them
PROFILE_EVALUATIONS = 12
EQUAL_FIT = 0.01  # two fits whose rms errors differ by less than this share explain the data equally
NAMED_BELOW = 0.75  # a model is named when its held-out error is below this share of "no control action"
DETERMINED_STD = 0.10  # relative std at most, for a fitted parameter to be given as determined
MIN_FLAT_S = 0.012  # a recorded output on a limit: flat at its extreme at least this long
FLAT_NOISES = 6.0  # "flat": within this many output noises of the extreme (found on a 3-sample mean)
WANTED_NOISES = 5.0  # ... while the small-signal fit wants it this many noises further
LIMIT_RANGE = 0.10  # a reached limit is fitted within this share of the extreme it was found at
REFERENCE_SEARCH = (-0.5, 0.5)  # pu: a limited model's reference step is sized within this
# an input limit is looked for from this share of the error's largest swing beyond rest outwards
INPUT_LIMIT_FLOOR = 0.05
# ... and kept where the step tests' error falls by this share at least with it (a freed limit
# can always be put out of reach, so any fit is at least as good with it)
INPUT_LIMIT_GAIN = 0.2
OUTSIDE_LIMITS = 10.0  # a fit's residual where its limits cannot hold an operating point: x the output's range

Limits = dict[str, tuple[float, float, float]]  # limit -> (start, low, high), for a fit that frees it


@dataclass
class ControlFit:
    """A control model fitted to one kind's scenarios."""

    model: str
    kind: str
    parameters: dict[str, float | None]
    uncertainty: dict[str, float | None]
    identifiable: dict[str, bool]
    fit_rmse: float
    heldout_rmse: float | None
    none_heldout_rmse: float | None
    named: bool
    why: str
    references: dict[str, float] = field(default_factory=dict)
    alternatives: dict[str, float] = field(default_factory=dict)  # models that fit as well: their errors
    limits: Limits = field(default_factory=dict)  # the limits this fit freed (reached in the recordings)
    # an output limit not reached: the least it can be, in its own terms (the recordings went that far)
    seen: dict[str, float] = field(default_factory=dict)
    # the limits the fit pressed on an end of their range: it wants them where the recordings say
    # they cannot be (a constant ceiling asked to be both a no-load step's top and a loaded one's)
    pressed: list[str] = field(default_factory=list)

    def as_json(self) -> dict[str, Any]:
        """``model`` is null where none is named; ``fitted_model`` is the best candidate either way."""
        return {
            "model": self.model if self.named else None,
            "fitted_model": self.model,
            "parameters": self.parameters,
            "uncertainty": self.uncertainty,
            "identifiable": self.identifiable,
            "fit_rmse_pu": self.fit_rmse,
            "heldout_rmse_pu": self.heldout_rmse,
            "no_control_heldout_rmse_pu": self.none_heldout_rmse,
            "named": self.named,
            "why": self.why,
            "reference_steps": self.references,
            "fit_as_well": self.alternatives,
            "limits_reached": sorted(self.limits),  # fitted from the recordings' flat tops
            "limits_seen": self.seen,  # a limit not reached is at least this (the recordings went that far)
            "limits_pressed": sorted(self.pressed),  # pressed on an end of its range: flagged, and said
        }


def zero_phase(x: Array, dt: float, cutoff_hz: float = INPUT_CUTOFF_HZ) -> Array:
    """Zero-phase low-pass: the filter run forward, then backward."""
    forward = lowpass2(x, cutoff_hz, dt, steady_start=True)
    return lowpass2(forward[::-1], cutoff_hz, dt, steady_start=True)[::-1]


@dataclass
class ControlCase:
    name: str
    inputs: ControlInputs
    output: Array
    stepped: bool  # a reference step at the event
    levels: OperatingLevels | None = None  # an exciter's operating levels: what its limits are against
    # the step's size where the test sheet says it (signed), 1 where the recorded set-point is the
    # input (``inputs.reference_step`` then holds it as it moved); fitted otherwise
    reference: float | None = None

    def known_reference(self) -> float:
        """The reference step this case is played with when it is not fitted: the test sheet's, 0 unstepped."""
        return self.reference if self.stepped and self.reference is not None else 0.0


DE_EXCITED = 0.3  # V_t ending below this share of its pre-event value: the field was switched off


def regulator_out_of_loop(s: ScenarioData) -> str | None:
    """Why no voltage regulator was in the loop in the scenario, or None: a manual test (a
    field-current regulator held I_f, said by the map or manifest) or a de-excitation (the
    converter in inverter mode, or the field breaker open: V_t ends below DE_EXCITED of its start)."""
    if s.regulator == "manual":
        return "a manual test (a field-current regulator held I_f): the AVR was not in the loop"
    v0 = float(np.mean(s["v_t"][s.pre_slice()]))
    end = float(np.mean(s["v_t"][s.steady_slice()]))
    if v0 > 0 and end < DE_EXCITED * v0:
        return f"a de-excitation (V_t {v0:.3f} -> {end:.3f} pu): no regulator in the loop"
    return None


def acted_unrecorded(s: ScenarioData) -> bool:
    """Whether the test sheet says the scenario's stabiliser was on (``regulator: avr+pss``) and its
    output is not recorded: E_fd then answers a signal the recording does not have, so the
    exciter's fit leaves the scenario out and the stabiliser is fitted from its effect there
    (:mod:`phid_ros.controls.stabiliser_effect`)."""
    return s.regulator == STABILISER_ON and not s.has("v_s")


def _cases(
    scenarios: Sequence[ScenarioData], kind: str, role: str, kinds: Sequence[str] | None = None
) -> list[ControlCase]:
    _needs, _out, _stepped, fitted_kinds = KINDS[kind]
    picked = (
        control_case(s, kind)
        for s in scenarios
        if s.role == role
        and s.kind in (fitted_kinds if kinds is None else kinds)
        and not (kind == "exciter" and (regulator_out_of_loop(s) or acted_unrecorded(s)))
    )
    return [c for c in picked if c is not None]


def control_case(
    s: ScenarioData, kind: str, *, output: bool = True, v_t_rest: float | None = None
) -> ControlCase | None:
    """The scenario as a control's fit or play-in sees it: deviations from the pre-event state,
    the inputs smoothed zero-phase below ``INPUT_CUTOFF_HZ``, at ``FIT_RATE_HZ``; None where a
    channel the kind needs is not recorded. ``output=False`` (a play-in): the output channel may
    be missing (then zeros, and no reference step is sized on it). ``v_t_rest``: the V_t the
    regulator holds at rest where it is not the scenario's own pre-event V_t (a closed loop's
    machine, whose V_t is its own, against the recorded set point)."""
    kind_needs, out_channel, kind_stepped, _fitted = KINDS[kind]
    needs: tuple[str, ...] = kind_needs
    stepped_kinds: tuple[str, ...] = kind_stepped
    if not output and not s.has(out_channel):
        needs = tuple(c for c in needs if c != out_channel)
    if not s.has(*needs):
        return None
    if kind == "stabiliser" and s.has(out_channel):
        on = switched_on(s)
        if on is None or (on > 0 and on >= s.k_event - int(round(SWITCHED_OFF_S / s.dt))):
            return None  # off through the event (or switched on just before it): nothing to fit
        s = s.rows(on, s.n) if on else s
    pre = s.pre_slice()
    # an exciter's error takes the recorded stabiliser output where there is one (V_REF - V_C + V_S)
    channels = (*needs, "omega", "v_t", "p_e", *(("v_s",) if kind == "exciter" else ()))
    rest = {c: float(np.mean(s[c][pre])) for c in channels if s.has(c)}
    if v_t_rest is not None:
        rest["v_t"] = v_t_rest
    dev = {c: np.asarray(s[c], float) - rest[c] for c in channels if s.has(c)}
    if not all(np.all(np.isfinite(dev[c])) for c in needs):
        return None
    if out_channel not in dev:
        dev[out_channel] = np.zeros(s.n)
        stepped_kinds = ()
    k = fit_stride(s.dt)
    set_point = recorded_set_point(s) if kind == "exciter" else None
    step = (np.arange(s.n) >= s.k_event).astype(float)[::k] if set_point is None else set_point[::k]
    zero = np.zeros(len(step))
    x = ControlInputs(
        s.dt * k,
        zero_phase(dev["v_t"], s.dt)[::k] if "v_t" in dev else zero,
        zero_phase(dev["omega"], s.dt)[::k] if "omega" in dev else zero,
        step,
        float(np.mean(s["p_m"][pre])) if s.has("p_m") else math.nan,
        zero_phase(dev["p_e"], s.dt)[::k] if "p_e" in dev else None,
        zero_phase(dev["v_s"], s.dt)[::k] if "v_s" in dev else None,
    )
    levels = None
    if kind == "exciter" and s.has("v_f"):
        output0 = float(np.mean(s["v_f"][pre]))
        # the field current at rest is E_fd on the machine's base (the scenarios carry no I_fd)
        levels = OperatingLevels(float(np.mean(s["v_t"][pre])) + x.v_t, output0, output0)
    elif kind == "stabiliser" and s.has(out_channel):
        levels = OperatingLevels(float(np.mean(s["v_t"][pre])) + x.v_t, float(np.mean(s[out_channel][pre])), 0.0)
    stepped = s.kind in stepped_kinds
    reference = None
    if set_point is not None:
        # the set-point as recorded is the exciter's input: played as it moved, not a step sized
        stepped, reference = bool(np.any(set_point != 0.0)), 1.0
    elif stepped and s.reference_step is not None:
        # the test sheet's size, signed by the event's own direction (a step up, then the return)
        moved = float(np.mean(s["v_t"][s.steady_slice()])) - float(np.mean(s["v_t"][pre]))
        reference = math.copysign(s.reference_step, moved)
    return ControlCase(s.name, x, np.ascontiguousarray(dev[out_channel][::k]), stepped, levels, reference)


def recorded_set_point(s: ScenarioData) -> Array | None:
    """The regulator's recorded set-point (``v_ref``) as a deviation from its value before the
    event, on the scenario's samples; None where it is not recorded or not finite throughout. Its
    level before is a recorded value (the median of the pre-event samples), so a set-point that
    did not move is exactly zero there."""
    if not s.has("v_ref"):
        return None
    v = np.asarray(s["v_ref"], float)
    if not np.all(np.isfinite(v)):
        return None
    return v - float(np.median(v[s.pre_slice()]))


def switched_on(s: ScenarioData) -> int | None:
    """Where the scenario's recorded stabiliser output (``v_s``) was switched on: 0 unless it sits
    at exactly one value (a switched-off stabiliser's 0) for its first ``SWITCHED_OFF_S`` and
    starts to move before the event; None if it never moves (off throughout). An output that is
    still until the event and moves with it was on, answering it (a noiseless simulation's)."""
    y = np.asarray(s["v_s"], float)
    moved = np.flatnonzero(y != y[0])
    if not moved.size:
        return None
    first = int(moved[0])
    answering = first >= s.k_event - int(round(EVENT_MARGIN_S / s.dt))
    return first if first * s.dt >= SWITCHED_OFF_S and not answering else 0


def fit_stride(dt: float) -> int:
    """Samples of the recording per sample of the fit (``FIT_RATE_HZ``)."""
    return max(1, int(round(1.0 / (dt * FIT_RATE_HZ))))


def _references(cases: Sequence[ControlCase], predicted: Sequence[Array], unit: Sequence[Array]) -> list[float]:
    """Each stepped case's reference size by least squares (the response is linear in it)."""
    out = []
    for c, p, u in zip(cases, predicted, unit):
        if not c.stepped or c.reference is not None:
            out.append(c.known_reference())
            continue
        denom = float(u @ u)
        out.append(float(u @ (c.output - p)) / denom if denom > 0 else 0.0)
    return out


def _sized(
    model: type[ControlModel], values: dict[str, float], cases: Sequence[ControlCase]
) -> tuple[list[Array], list[Array], list[float]]:
    """Per case the small-signal response without a reference step, the response to a unit one
    (empty where the case has none) and the step's size by least squares (0 unstepped)."""
    free = [model.response(values, c.inputs, 0.0) for c in cases]
    unit = [model.response(values, c.inputs, 1.0) - f if c.stepped else np.zeros(0) for c, f in zip(cases, free)]
    return free, unit, _references(cases, free, unit)


def simulate_references(
    model: type[ControlModel], values: dict[str, float], cases: Sequence[ControlCase]
) -> list[float]:
    """Each case's reference step as the small-signal model sizes it."""
    return _sized(model, values, cases)[2]


def simulate_cases(model: type[ControlModel], values: dict[str, float], cases: Sequence[ControlCase]) -> list[Array]:
    """Each case's output with its reference step sized by least squares."""
    free, unit, refs = _sized(model, values, cases)
    return [f + r * u if c.stepped else f for c, f, u, r in zip(cases, free, unit, refs)]


def limited_output(
    model: type[ControlModel], values: Mapping[str, float], case: ControlCase, reference: float | None = None
) -> tuple[Array, float]:
    """The case's output deviation played through the model's limits, and its reference step:
    ``reference``, or for a stepped case without one the size a bounded search finds (the
    response is not linear in it). Raises LimitsError where the limits cannot hold the case's
    operating point."""
    from scipy.optimize import minimize_scalar

    assert case.levels is not None
    levels = case.levels

    def played(r: float) -> Array:
        out = model.limited(values, case.inputs, r, levels)
        if out is None:
            raise LimitsError(f"{model.name} simulates no limits")
        return out

    if reference is None:
        reference = case.known_reference()
        if case.stepped and case.reference is None:
            reference = float(
                minimize_scalar(
                    lambda r: float(np.sum((played(r) - case.output) ** 2)),
                    bounds=REFERENCE_SEARCH,
                    method="bounded",
                    options={"xatol": 1e-5},
                ).x
            )
    return played(reference), reference


def reached_limits(
    model: type[ControlModel], values: Mapping[str, float], cases: Sequence[ControlCase], noise: float
) -> Limits:
    """The output limits the recordings reached (see the module's note), each with where its fit
    starts and its range: the recorded extreme it sat at, in the limit's own terms.

    Found: a limit hit at speed (a fault drives E_fd to its ceiling within tens of ms) or one the
    small-signal fit wants past. Not found: a limit crept up to (E_fd sliding to its floor over
    a second through a long lead-lag) that the small-signal fit, bent by that very case, does
    not want past; the fit's constants are then flagged as the profile finds them, not freed.
    Never inside what any case's output reached: behind ANDES's EXST1 input limit E_fd rose to
    5.01 in a V_ref step, and SEXS's E_MAX, freed down to 4.3, sat at 4.59 to mimic that limit."""
    if model.output_limits is None or not any(c.levels is not None for c in cases):
        return {}
    lower, upper = model.output_limits
    found: dict[str, float] = {}
    rest: dict[str, float] = {}  # the limit's value at each case's operating point: it must hold them all
    reached: dict[str, float] = {}  # the outermost the output went, in the limit's terms
    pred = simulate_cases(model, {**model.defaults(), **values}, cases)
    for c, want in zip(cases, pred):
        if c.levels is None or c.output.size < 3:
            continue
        for sign, name in ((1.0, upper), (-1.0, lower)):
            at_rest = model.limit_at(name, c.levels.output0, c.levels, 0)
            rest[name] = at_rest if name not in rest else sign * max(sign * rest[name], sign * at_rest)
        flat_n = max(3, int(math.ceil(MIN_FLAT_S / c.inputs.dt)))
        span = float(np.ptp(c.output))
        tol = max(FLAT_NOISES * noise, 0.002 * span)
        for sign, name in ((1.0, upper), (-1.0, lower)):
            y = sign * c.output
            # the top found on the output averaged over the flat span: a lone noise peak is no top
            top = np.convolve(y, np.ones(flat_n) / flat_n, mode="same")
            k = int(np.argmax(top[flat_n:-flat_n])) + flat_n if len(y) > 3 * flat_n else int(np.argmax(top))
            level = float(top[k])
            # a limit is never inside what the output reached (less its noise), wherever it did
            beyond = model.limit_at(name, c.levels.output0 + sign * (level - tol), c.levels, k)
            if name not in reached or sign * beyond > sign * reached[name]:
                reached[name] = beyond
            on = top >= level - tol
            # the run of flat samples around the extreme
            a = k
            while a > 0 and on[a - 1]:
                a -= 1
            b = k
            while b + 1 < len(y) and on[b + 1]:
                b += 1
            if b - a + 1 < flat_n:
                continue
            # a limit is hit: the output arrives at speed and stops dead (a settling output creeps
            # up to its plateau); or the fit wants it further. Either: a limit, not a plateau
            hit = a >= 2 and float(level - top[a - 2]) > 3.0 * tol
            wanted = float(np.mean(sign * want[a : b + 1])) >= level + WANTED_NOISES * max(noise, 1e-9)
            if not (hit or wanted):
                continue
            at = model.limit_at(name, c.levels.output0 + sign * level, c.levels, k)
            # the limit is one value: the outermost flat top found (a case that sat lower was
            # held there by something else)
            if name not in found or sign * at > sign * found[name]:
                found[name] = at
    out: Limits = {}
    for name, at in found.items():
        sign = 1.0 if name == upper else -1.0
        # the range in terms of the limit's size or its distance from rest (a floor at 0 pu)
        scale = max(abs(at), abs(at - rest[name]))
        near, far = at - sign * LIMIT_RANGE * scale, at + sign * LIMIT_RANGE * scale
        # never inside an operating point a case rested at (the limit held it), by a margin
        margin = 0.01 * scale
        near = sign * max(sign * near, sign * rest[name] + margin, sign * reached[name])
        if sign * far <= sign * near:
            continue
        lo, hi = sorted((near, far))
        out[name] = (min(max(at, lo), hi), lo, hi)
    return out


def limits_seen(
    model: type[ControlModel], cases: Sequence[ControlCase], reached: Mapping[str, Any]
) -> dict[str, float]:
    """Each output limit not ``reached``: the outermost value the recorded output implies, in the
    limit's terms (a static exciter's E_fd of 4.8 at V_T 0.19 in a fault: V_RMAX at least 25). A
    record that writes a limit below it would cut what was recorded."""
    if model.output_limits is None:
        return {}
    lower, upper = model.output_limits
    out: dict[str, float] = {}
    for c in cases:
        if c.levels is None or not c.output.size:
            continue
        y = c.levels.output0 + c.output
        for sign, name in ((1.0, upper), (-1.0, lower)):
            if name in reached:
                continue
            at = max(sign * model.limit_at(name, float(y[k]), c.levels, k) for k in range(len(y)))
            out[name] = sign * max(at, sign * out[name]) if name in out else sign * at
    return out


def _no_control(cases: Sequence[ControlCase]) -> list[Array]:
    """The output held, but for each reference step (its size by least squares)."""
    out = []
    for c in cases:
        u = c.inputs.reference_step
        r = float(u @ c.output) / float(u @ u) if c.stepped else 0.0
        out.append(r * u)
    return out


def _output_noise(cases: Sequence[ControlCase]) -> float:
    """The output's noise (pu rms) before the events: its sample-to-sample differences over sqrt(2),
    which a slow drift does not reach."""
    diffs = [np.diff(c.output[c.inputs.reference_step == 0]) for c in cases]
    d = np.concatenate([x for x in diffs if x.size]) if any(x.size for x in diffs) else np.zeros(0)
    return float(np.sqrt(np.mean(d**2) / 2.0)) if d.size else 0.0


def _rmse(cases: Sequence[ControlCase], predicted: Sequence[Array]) -> float:
    err = np.concatenate([c.output - p for c, p in zip(cases, predicted)]) if cases else np.zeros(0)
    return float(np.sqrt(np.mean(err**2))) if err.size else math.nan


def fit_model(
    model: type[ControlModel],
    fit: Sequence[ControlCase],
    held: Sequence[ControlCase],
    earlier: Mapping[str, Mapping[str, float]] | None = None,
    *,
    checked: bool = True,
    start_at: Mapping[str, float] | None = None,
    limits: Limits | None = None,
    held_limits: Mapping[str, float] | None = None,
    played_through_limits: bool = False,
) -> ControlFit:
    """``model``'s fitted parameters (log scale, in their ranges; the limits held), their stds
    from the Jacobian, and its error on the held-out cases; started where ``model.start`` says
    from the ``earlier`` models' fits. ``checked``: a constant is given as determined only after
    a second start and a profile agree (the named model's fit); unchecked fits only compete.
    ``limits``: the output limits the recordings reached (:func:`reached_limits`), fitted too,
    the cases played through them (:meth:`ControlModel.limited`), each stepped case's reference
    a constant of the fit. ``held_limits``: limits found by such a fit, held at their values while
    the small-signal constants are fitted and checked on the small-signal tests alone.
    ``played_through_limits``: the cases played through :meth:`ControlModel.limited` whatever
    limits are fitted (a stabiliser fitted through an exciter that reached its own)."""
    from phid_ros import tall_least_squares

    limits = dict(limits or {})
    held_limits = dict(held_limits or {})
    through_limits = bool(limits or held_limits or played_through_limits)
    bounded = [replace(q, default=limits[q.name][0], low=limits[q.name][1], high=limits[q.name][2], limit=False)
               for q in model.parameters if q.name in limits]  # fmt: skip
    n_model = len(model.fitted()) + len(bounded)
    stepped = [i for i, c in enumerate(fit) if c.stepped and c.reference is None] if through_limits else []
    references = [
        ControlParameter(f"reference {fit[i].name}", "pu", 0.0, *REFERENCE_SEARCH, "the case's reference step")
        for i in stepped
    ]
    free = [*model.fitted(), *bounded, *references]
    values0 = model.defaults() | open_limits(model) | held_limits
    log = [p.low > 0 for p in free]

    def values_at(x: Array) -> dict[str, float]:
        v = dict(values0)
        for p, xi, lg in zip(free[:n_model], x, log):
            v[p.name] = float(np.exp(xi)) if lg else float(xi)
        return model.completed(v)

    def wall() -> list[Array]:
        return [c.output + OUTSIDE_LIMITS * np.maximum(np.ptp(c.output), 1e-3) for c in fit]

    def predicted(x: Array) -> list[Array]:
        values = values_at(x)
        if not through_limits:
            out = simulate_cases(model, values, fit)
        else:
            refs = dict(zip(stepped, (float(r) for r in x[n_model:])))
            try:
                out = [limited_output(model, values, c, refs.get(i, c.known_reference()))[0] for i, c in enumerate(fit)]
            except LimitsError:
                # limits that cannot hold an operating point at these constants (an input limit below
                # E_fd / K_A as K_A falls): a wall the search turns back from, not an answer
                return wall()
        # a play that diverged at these constants (a build-up's ceiling through an input limit on
        # Zakucac's day): a wall too; least_squares stopped with "Residuals are not finite"
        return out if all(np.all(np.isfinite(p)) for p in out) else wall()

    def residual(x: Array) -> Array:
        return np.concatenate([c.output - p for c, p in zip(fit, predicted(x))])

    lo = np.array([math.log(p.low) if lg else p.low for p, lg in zip(free, log)])
    hi = np.array([math.log(p.high) if lg else p.high for p, lg in zip(free, log)])
    first = {**model.defaults(), **start_at} if start_at else model.start(earlier or {})
    first |= {q.name: q.default for q in bounded if not (start_at and q.name in start_at)}
    if stepped:  # the references start where the small-signal model sizes them
        lin = simulate_references(model, model.completed({**values0, **first}), [fit[i] for i in stepped])
        first |= {q.name: min(max(r, q.low), q.high) for q, r in zip(references, lin)}
    x0 = np.array([math.log(max(first[p.name], p.low)) if lg else first[p.name] for p, lg in zip(free, log)])
    # least_squares' trust region does not leave a bound it starts on (IEEET1's T_R stayed at 0
    # and T_A took both lags, +40 %): every start is moved inside by 2 % of its range
    inset = 0.02 * (hi - lo)
    x0 = np.clip(x0, lo + inset, hi - inset)

    # the cases' rows (every sample of every case) compressed to k + 1 for the solver: its SVD of
    # the full Jacobian at every step was half the exciter search of a commissioning day
    def solve(start: Array) -> tall_least_squares.Solution:
        return tall_least_squares.solve(residual, start, lo, hi, MAX_EVALUATIONS)

    sol = solve(x0)

    def solve_fixed(i: int, value: float, start: Array) -> float:
        keep = np.arange(len(free)) != i

        def res(y: Array) -> Array:
            x = start.copy()
            x[keep], x[i] = y, value
            return residual(x)

        return tall_least_squares.solve(res, start[keep], lo[keep], hi[keep], PROFILE_EVALUATIONS).cost

    # a second opinion from a start moved away in every constant (alternate signs): where both
    # fits explain the data equally well but a constant differs, the data do not determine it,
    # whatever the Jacobian at either says (ESST5B's T_B2 came out 0.019 +- 0.0015 from one
    # start and 0.010 +- 0.032 from another, with the same error; the truth was 0.010)
    signs = np.where(np.arange(len(free)) % 2 == 0, 1.0, -1.0)
    other = solve(np.clip(sol.x + signs * SECOND_START * (hi - lo), lo + inset, hi - inset)) if checked else sol
    if other.cost < sol.cost:
        sol, other = other, sol
    equal_fit = checked and other.cost <= (1.0 + EQUAL_FIT) ** 2 * sol.cost
    values = values_at(sol.x)
    # the residuals of one scenario are correlated (its dynamics, the smoothing): clustered by
    # scenario, not the textbook s^2 (J'J)^-1, which gave T_E 0.0468 +- 0.0001 for a true 0.05
    blocks = block_ids([c.output.size for c in fit], max(c.output.size for c in fit))
    cov = cluster_robust_cov(np.asarray(sol.jac), np.asarray(sol.fun), blocks)
    std_x = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    at_bound = (np.abs(sol.x - lo) < 1e-6) | (np.abs(sol.x - hi) < 1e-6)
    # a limit's range ends where the recordings say it cannot be (inside what the output reached,
    # or an operating point it held): one pressed within a thousandth of that end is flagged
    # (Mostar's V_RMIN sat 0.0003 from the lowest the output went, "determined")
    edge = 1e-3 * (hi - lo)
    ends = {n for pair in (model.output_limits, model.input_limits) if pair is not None for n in pair}
    pressed = []
    for i in range(len(model.fitted()), n_model):
        at_edge = bool(min(sol.x[i] - lo[i], hi[i] - sol.x[i]) < edge[i])
        at_bound[i] |= at_edge
        if at_edge and free[i].name in ends:
            pressed.append(free[i].name)
    # the Jacobian's std is local: where the error hardly changes with a constant moved by
    # DETERMINED_STD either way (the others refitted), the data do not determine it (HYGOV's T_r
    # on 12 s windows: 4.407 +- 0.21 for a true 5.0, the truth's error 0.02 % above the fit's).
    # "Hardly": less than two standard errors' worth of chi-square, 4/N_eff, N_eff the residuals'
    # count shrunk by their lag-1 correlation
    r = np.asarray(sol.fun, float)
    rho = float(np.clip(np.dot(r[1:], r[:-1]) / max(float(np.dot(r, r)), 1e-300), 0.0, 0.99))
    significant = 4.0 / max(r.size * (1.0 - rho) / (1.0 + rho), 1.0)
    raw = [float(np.exp(xi)) if lg else float(xi) for xi, lg in zip(sol.x, log)]
    raw_other = [float(np.exp(xi)) if lg else float(xi) for xi, lg in zip(other.x, log)]
    stds, determined = [], []
    # a time constant is known to a quarter of the fit's sample at best (1 ms at 250 Hz): a
    # limiter switches somewhere within a step of whatever made the recording (ANDES's 2 ms put
    # T_R 0.0179 and T_A 0.0223 for 0.02 each, T_A's Jacobian std 26 us)
    resolution = 0.25 * min(c.inputs.dt for c in fit)
    for i in range(n_model):  # the references are the cases' own, not the model's: not judged
        sd = raw[i] * float(std_x[i]) if log[i] else float(std_x[i])
        if free[i].unit == "s":
            sd = max(sd, resolution)
        scale = DETERMINED_STD * max(abs(raw[i]), 1e-9)
        ok = not at_bound[i] and math.isfinite(sd) and sd <= scale
        ok = ok and (not equal_fit or abs(raw_other[i] - raw[i]) <= scale)
        ok = ok and (not checked or _profile_rise(solve_fixed, sol, i, log[i], lo, hi) >= significant)
        stds.append(sd)
        determined.append(ok)
    params: dict[str, float | None] = {}
    std: dict[str, float | None] = {}
    ident: dict[str, bool] = {}
    for i, p in enumerate(free[:n_model]):
        # where the model's completion moved a value to another name (IEEEG1's commuting lags,
        # put in order), its std and verdict go with it
        j = next((k for k, v in enumerate(raw[:n_model]) if v == values[p.name]), i)
        params[p.name], std[p.name], ident[p.name] = values[p.name], stds[j], bool(determined[j])
    for p in model.parameters:
        if p.limit and p.name in held_limits:  # found by the fit with the faults (the caller's verdict)
            params[p.name], std[p.name], ident[p.name] = held_limits[p.name], None, False
        elif p.limit and p.name not in limits:  # never reached: the data say nothing of it
            params[p.name], std[p.name], ident[p.name] = None, None, False
        elif p.held:  # the model's structure sets it (a stage left out, a share that completes another)
            params[p.name], std[p.name], ident[p.name] = values[p.name], None, False
    pred = predicted(sol.x)
    if through_limits:
        refs = [
            float(sol.x[n_model + stepped.index(i)]) if i in stepped else c.known_reference() for i, c in enumerate(fit)
        ]
        held_pred = [limited_output(model, values, c)[0] for c in held]
    else:
        refs = simulate_references(model, values, fit)
        held_pred = simulate_cases(model, values, held)
    held_rmse = _rmse(held, held_pred) if held else None
    return ControlFit(
        model.name,
        model.kind,
        params,
        std,
        ident,
        _rmse(fit, pred),
        held_rmse,
        None,
        False,
        "",
        {c.name: r for c, r in zip(fit, refs) if c.stepped},
        limits=limits,
        pressed=pressed,
    )


def open_limits(model: type[ControlModel]) -> dict[str, float]:
    """The model's output and input limits out of reach: a limit the recordings did not reach
    does not act in a fit played through the others (its default would: SEXS's E_MAX 5)."""
    out: dict[str, float] = {}
    for pair in (model.output_limits, model.input_limits):
        if pair is not None:
            out |= {pair[0]: -math.inf, pair[1]: math.inf}
    return out


def wanted_input_limits(model: type[ControlModel], values: Mapping[str, float], cases: Sequence[ControlCase]) -> Limits:
    """Where a fit may put the model's input limits (its error's VIMIN, VIMAX): between the error at
    rest and the largest the small-signal model drives it to in the recordings, either way. No
    flat top shows an input limit (behind a lead-lag the output keeps moving), so these are
    candidates: the fit that frees them is kept only where it binds and explains clearly more
    (see :func:`_with_reached_limits`)."""
    if model.input_limits is None or not any(c.levels is not None for c in cases):
        return {}
    full = model.completed({**model.defaults(), **values})
    refs = simulate_references(model, full, cases)
    highest, lowest, rest_hi, rest_lo = -math.inf, math.inf, -math.inf, math.inf
    for c, r in zip(cases, refs):
        if c.levels is None:
            continue
        try:
            e = model.input_signal(full, c.inputs, r, c.levels)
        except LimitsError:
            continue
        if e is None or not e.size:
            continue
        highest, lowest = max(highest, float(np.max(e))), min(lowest, float(np.min(e)))
        rest_hi, rest_lo = max(rest_hi, float(e[0])), min(rest_lo, float(e[0]))
    if not math.isfinite(highest):
        return {}
    lower, upper = model.input_limits
    out: Limits = {}
    # the swing beyond rest on each side; a limit is looked for within it, never inside the rest
    for name, far, rest, sign in ((upper, highest, rest_hi, 1.0), (lower, lowest, rest_lo, -1.0)):
        swing = sign * (far - rest)
        if swing <= 0:
            continue
        near = rest + sign * INPUT_LIMIT_FLOOR * swing
        lo, hi = sorted((near, far))
        out[name] = (rest + sign * 0.5 * swing, lo, hi)
    return out


def _binding(
    model: type[ControlModel], limited: ControlFit, cases: Sequence[ControlCase], noise: float
) -> tuple[list[Array], list[str]]:
    """The cases played through ``limited``'s limits, and the limits it freed that never bind
    there (moved out of reach, no case's output moves by more than the noise)."""
    values = model.completed({**model.defaults(), **open_limits(model), **_known(limited)})
    refs = limited.references
    played = [limited_output(model, values, c, refs.get(c.name, 0.0))[0] for c in cases]
    uppers = {p[1] for p in (model.output_limits, model.input_limits) if p is not None}
    idle = []
    for name in limited.limits:
        # a limit out of reach; a loading factor where it vanishes
        far = {**values, name: 1e9 if name in uppers else 0.0 if name == model.loading else -1e9}
        free = [limited_output(model, far, c, refs.get(c.name, 0.0))[0] for c in cases]
        with np.errstate(invalid="ignore"):  # a play that diverged without the limit: the limit acts
            moved = max(float(np.max(np.abs(a - b))) for a, b in zip(played, free))
        if moved < WANTED_NOISES * max(noise, 1e-9):  # NaN: not idle
            idle.append(name)
    return played, idle


def _with_reached_limits(
    model: type[ControlModel],
    small_signal: ControlFit,
    fit: Sequence[ControlCase],
    faults: Sequence[ControlCase],
    held: Sequence[ControlCase],
) -> ControlFit:
    """``small_signal`` refitted with the output limits the recordings reached, the faults joining
    the fit; as it was where none is reached (or the limits found cannot hold a case's operating
    point). Then, for a model with input limits, refitted with those freed too, kept where they
    bind and the step tests' error falls by ``INPUT_LIMIT_GAIN`` at least."""
    cases = [*fit, *faults]
    noise = _output_noise(fit)
    outcome = small_signal
    limits = reached_limits(model, _known(small_signal), cases, noise)
    if limits:
        if model.loading is not None and model.output_limits and model.output_limits[1] in limits:
            # a ceiling lowered by the field current (K_C I_FD): freed with it, so tops reached at
            # different field currents are one ceiling (Mostar's no-load and on-line steps sat 4 %
            # apart in V_T terms; the published ST5B has K_C 0.98)
            q = next(p for p in model.parameters if p.name == model.loading)
            limits = {**limits, q.name: (0.5 * (q.low + q.high), q.low, q.high)}
        try:
            limited = fit_model(model, cases, held, checked=False, start_at=_known(small_signal), limits=limits)
            played, idle = _binding(model, limited, cases, noise)
            if idle == [model.loading]:  # the loading does not show: the ceiling alone
                limits = {k: v for k, v in limits.items() if k != model.loading}
                limited = fit_model(model, cases, held, checked=False, start_at=_known(limited), limits=limits)
                played, idle = _binding(model, limited, cases, noise)
        except LimitsError:
            limited, idle = small_signal, []
        # a limit the fit put where it never binds was no limit (a fast step onto a flat plateau
        # looks like one): its value would carry no information, and its std none either
        if limited is not small_signal and not idle:
            # judged on the cases the other models' fits are (the step tests), not on the faults too
            limited.fit_rmse = _rmse(fit, played[: len(fit)])
            outcome = limited
    # the input limits freed from the small-signal fit alone and beside the output limits found:
    # an input limit flattens E_fd's rise behind a slow lag, which reads as a flat top, so each
    # start may fall into the other's local minimum (EXST1 from SEXS's fit put VIMIN at rest)
    trials = [
        _with_input_limits(model, base, fit, faults, held, noise)
        for base in ((small_signal, outcome) if outcome is not small_signal else (small_signal,))
    ]
    freed = min((f for f in trials if f is not None), key=lambda f: f.fit_rmse, default=None)
    if freed is None or freed.fit_rmse > (1.0 - INPUT_LIMIT_GAIN) * outcome.fit_rmse:
        return outcome
    return freed


def _with_input_limits(
    model: type[ControlModel],
    base: ControlFit,
    fit: Sequence[ControlCase],
    faults: Sequence[ControlCase],
    held: Sequence[ControlCase],
    noise: float,
) -> ControlFit | None:
    """``base`` refitted with its input limits freed one side at a time, the side the error
    swings furthest past rest first, the faults joining the fit; a further side kept only where
    the step tests' error falls by ``INPUT_LIMIT_GAIN`` with it (both freed at once, a side the
    error barely passed put VIMIN at rest and sent K_A from 238 to 22). None where no input
    limit binds. ``fit_rmse`` on the step tests."""
    cases = [*fit, *faults]
    wanted = wanted_input_limits(model, _known(base), cases)
    current: ControlFit | None = None
    for name in sorted(wanted, key=lambda n: wanted[n][1] - wanted[n][2]):
        start = current or base
        try:
            freed = _freed(model, start, {**start.limits, name: wanted[name]}, name, cases, held, noise)
        except LimitsError:
            continue
        if freed is None:
            continue
        freed.fit_rmse = _rmse(fit, _binding(model, freed, cases, noise)[0][: len(fit)])
        if current is None or freed.fit_rmse <= (1.0 - INPUT_LIMIT_GAIN) * current.fit_rmse:
            current = freed
    return current


def _freed(
    model: type[ControlModel],
    start: ControlFit,
    trial: Limits,
    name: str,
    cases: Sequence[ControlCase],
    held: Sequence[ControlCase],
    noise: float,
) -> ControlFit | None:
    """``start`` refitted with the limits ``trial`` free; the ones that never bind dropped and the
    rest refitted, None where ``name`` (the side being tried) does not bind."""
    uppers = {p[1] for p in (model.output_limits, model.input_limits) if p is not None}
    freed = fit_model(model, cases, held, checked=False, start_at=_known(start), limits=trial)
    idle = _binding(model, freed, cases, noise)[1]
    # an output limit the fit now pushes to the far end of its range was a top the input limit
    # flattened (behind a slow lag E_fd barely rises): no limit of its own
    idle += [
        n
        for n in start.limits
        if n not in idle
        and n not in (model.input_limits or ())
        and math.isclose(freed.parameters[n] or 0.0, trial[n][2 if n in uppers else 1], rel_tol=1e-4)
    ]
    if name in idle:
        return None
    if idle:
        trial = {k: v for k, v in trial.items() if k not in idle}
        freed = fit_model(model, cases, held, checked=False, start_at=_known(freed), limits=trial)
        if _binding(model, freed, cases, noise)[1]:
            return None
    return freed


def _on_step_tests(
    model: type[ControlModel], limited: ControlFit, fit: Sequence[ControlCase], held: Sequence[ControlCase]
) -> ControlFit:
    """A fit that found limits, its small-signal constants refitted on the step tests alone with
    the output limits held (the input limits free): how the named model's constants are given,
    so the models compete on it. Judged on the fit with the faults instead, STEPS's own SEXS erred
    0.0158 pu held out against IEEET1's 0.0085 (no limit, no fault) and lost to it; refitted, 0.0084."""
    if not limited.limits:
        return limited
    try:
        refit = _refit_through_limits(model, limited, fit, held, checked=False)
    except LimitsError:
        return limited
    for n in _limit_values(limited):
        refit.parameters[n], refit.uncertainty[n] = limited.parameters[n], limited.uncertainty[n]
        refit.identifiable[n] = limited.identifiable[n]
    refit.limits = limited.limits
    refit.pressed = sorted({*refit.pressed, *(n for n in limited.pressed if n in _limit_values(limited))})
    return refit


def _refit_through_limits(
    model: type[ControlModel],
    f: ControlFit,
    fit: Sequence[ControlCase],
    held: Sequence[ControlCase],
    *,
    checked: bool,
) -> ControlFit:
    """``model`` fitted on ``fit`` from ``f``'s constants, played through the limits ``f`` found:
    its output limits held, its input limits fitted again."""
    return fit_model(
        model, fit, held, checked=checked, start_at=_known(f), limits=_input_limits(f), held_limits=_limit_values(f)
    )


def _limit_values(f: ControlFit) -> dict[str, float]:
    """The values of the output limits ``f`` freed (found reached): held while the small-signal
    constants are fitted on the step tests, which a fault's ceiling is not seen in."""
    inputs = MODELS[f.model].input_limits or ()
    return {n: float(v) for n in f.limits if n not in inputs and (v := f.parameters.get(n)) is not None}


def _input_limits(f: ControlFit) -> Limits:
    """The input limits ``f`` freed, from its values within their search ranges: fitted again with
    the small-signal constants, since a step test reaches them too (a V_ref step of 0.15 an input
    limit of 0.1) and, held at a fault's value, the step tests' constants bend around them."""
    inputs = MODELS[f.model].input_limits or ()
    return {n: (float(v), *f.limits[n][1:]) for n in f.limits if n in inputs and (v := f.parameters.get(n)) is not None}


def _known(f: ControlFit) -> dict[str, float]:
    return {k: v for k, v in f.parameters.items() if v is not None}


def _holding(model: type[ControlModel], name: str) -> type[ControlModel]:
    """``model`` with constant ``name`` held where its term vanishes, and the constants of that
    term (a rate feedback's T_F with its K_F) held with it: moot."""
    from dataclasses import replace

    def held(p: ControlParameter) -> ControlParameter:
        if p.name == name and p.absent is not None:
            return replace(p, default=p.absent, low=p.absent, high=p.absent, held=True)
        return replace(p, held=True) if p.within == name else p

    return type(model.__name__, (model,), {"parameters": tuple(held(p) for p in model.parameters)})


def _without_unseen_terms(
    model: type[ControlModel], fitted: ControlFit, fit: Sequence[ControlCase], held: Sequence[ControlCase]
) -> type[ControlModel]:
    """The model with each term the recordings do not show held where it vanishes, one at a time
    while the fit's error rises by less than ``EQUAL_FIT``: a rate feedback of a static exciter
    that has none (EXST1 with K_F = 0) otherwise trades with its lead-lag, and neither is
    determined."""
    for p in model.parameters:
        if p.absent is None or p.held or p.limit:
            continue
        trial = _holding(model, p.name)
        f = _refit_through_limits(trial, fitted, fit, held, checked=False)
        if f.fit_rmse <= (1.0 + EQUAL_FIT) * fitted.fit_rmse:
            model, fitted = trial, f
    return model


def _profile_rise(solve_fixed: Any, sol: Any, i: int, log: bool, lo: Array, hi: Array) -> float:
    """The least relative rise of the fit's cost with constant ``i`` moved by DETERMINED_STD either
    way and the others refitted."""
    rises = []
    for sign in (-1.0, 1.0):
        x = float(sol.x[i])
        moved = x + sign * math.log1p(DETERMINED_STD) if log else x * (1.0 + sign * DETERMINED_STD)
        if not lo[i] <= moved <= hi[i]:
            continue
        rises.append(solve_fixed(i, moved, np.asarray(sol.x, float)) / float(sol.cost) - 1.0)
    return min(rises) if rises else math.inf


def _judged(f: ControlFit) -> float:
    """A fit's error as the choice sees it: held out, or its own without validation scenarios."""
    e = f.heldout_rmse if f.heldout_rmse is not None else f.fit_rmse
    return e if math.isfinite(e) else math.inf


def _simplest_best(fits: Sequence[ControlFit]) -> tuple[ControlFit, list[ControlFit]]:
    """The fit with the fewest fitted constants among those within ``SIMPLEST_WITHIN`` of the best
    error (registration order among equals), and the others within it: a model that nests another
    (EXST1 with T_R and K_F at 0 is SEXS) fits its data as well, and the data do not show the extra
    blocks; two that do not nest may still answer alike (IEEET1's rate feedback around a large
    K_A is EXST1's transient gain reduction), and the recordings cannot tell them apart."""
    best = min(_judged(f) for f in fits)
    close = [f for f in fits if _judged(f) <= SIMPLEST_WITHIN * best]
    chosen = min(close, key=lambda f: len(MODELS[f.model].fitted()))
    return chosen, [f for f in close if f is not chosen]


def on_machine_field_base(
    scenarios: Sequence[ScenarioData], saturation: tuple[float, float] | None = None
) -> tuple[list[ScenarioData], str | None]:
    """The scenarios with the recorded E_fd put on the machine's base where the no-load tests show
    it recorded on another (an excitation controller's own per unit: V_t settles at 2.68 x E_fd,
    outside what saturation explains), and the note saying so; as they are otherwise. Where the
    field current is recorded, file by file from it (:func:`phid_ros.ident.field_circuit.machine_field`:
    a test's field resistance moves with its temperature); else from E_fd's own no-load plateaus.
    The curve is ``saturation`` (the datasheet's S(1.0), S(1.2), held, which ``phid export``
    writes into the record) or the air-gap line, as ``phid validate`` takes it from a record
    without saturation: an exciter's gain fitted on it plays back on the same base."""
    from phid_ros.ident.determinable import FIELD_GAIN_BAND
    from phid_ros.ident.field_circuit import machine_field
    from phid_ros.ident.open_circuit import field_base
    from phid_ros.ident.terminal import with_channels

    by_current = machine_field(scenarios, saturation)
    if by_current is not None:
        if by_current.on_base():
            return list(scenarios), None
        note = f"the exciter fitted with {by_current.note}"
        return by_current.applied(scenarios, note), note
    base = field_base(scenarios)
    if base is None or FIELD_GAIN_BAND[0] <= base.scale <= FIELD_GAIN_BAND[1]:
        return list(scenarios), None
    k = base.scale
    note = (
        f"the exciter fitted with E_fd on the machine's base: 1 pu = {1 / k:.4g} as recorded, from "
        f"{len(base.v_t)} no-load plateau(s) at V_t {base.v_t.min():.3f}-{base.v_t.max():.3f} pu on the air-gap "
        f"line (within {100 * base.scatter:.1f} %; the saturation not known here): every E_fd multiplied by {k:.4g}"
    )
    out = [with_channels(s, {"v_f": k * np.asarray(s["v_f"], float)}, note) if s.has("v_f") else s for s in scenarios]
    return out, note


def controls_json(found: dict[str, ControlFit | str]) -> dict[str, Any]:
    """identify's JSON ``controls``: per kind the fit, or ``{"model": null, "why": ...}``."""
    return {k: f.as_json() if isinstance(f, ControlFit) else {"model": None, "why": f} for k, f in found.items()}


def identify_machine_controls(
    scenarios: Sequence[ScenarioData],
    route_details: Mapping[str, Any],
    saturation: tuple[float, float] | None,
    candidates: Mapping[str, Sequence[str]] | None = None,
    starts: Mapping[str, Mapping[str, float]] | None = None,
    kinds: Sequence[str] | None = None,
) -> tuple[list[ScenarioData], dict[str, ControlFit | str], list[str]]:
    """The control systems of a machine just identified (its ``route_details``), as ``phid
    identify`` and the monitor's recalibration both fit them: E_fd put on the machine's base
    (:func:`on_machine_field_base`), then :func:`identify_controls`; an exciter is not fitted from
    field channels that gave the machine an impossible value
    (:func:`phid_ros.ident.determinable.impossible_field`). Returns (the scenarios with E_fd on the
    machine's base, the fits, notes for the user)."""
    from phid_ros.controls.models import KINDS_IN_ORDER
    from phid_ros.ident.determinable import impossible_field

    on_base, base_note = on_machine_field_base(scenarios, saturation)
    notes = [base_note] if base_note else []
    distrust = impossible_field(route_details)
    wanted = [k for k in (kinds or KINDS_IN_ORDER) if not (distrust and k == "exciter")]
    found = identify_controls(on_base, candidates, starts, wanted)
    if distrust and "exciter" in (kinds or KINDS_IN_ORDER):
        found = {"exciter": f"not identified: {distrust}", **found}
        notes.append(f"the exciter is not identified: {distrust}")
    return on_base, found, notes


def identify_controls(
    scenarios: Sequence[ScenarioData],
    candidates: Mapping[str, Sequence[str]] | None = None,
    starts: Mapping[str, Mapping[str, float]] | None = None,
    kinds: Sequence[str] | None = None,
) -> dict[str, ControlFit | str]:
    """For each kind (exciter, governor, stabiliser): the named model's fit, or why none is named.

    ``candidates`` restricts a kind to the models named (a plant engineer who knows the unit's
    exciter is static says EXST1); the default is every registered model of the kind.
    ``starts``: per kind, constants of a model the user has (an existing .dyr's), where the fit
    of the model they belong to starts. ``kinds``: only these (default every kind)."""
    out: dict[str, ControlFit | str] = {}
    for kind in KINDS if kinds is None else [k for k in KINDS if k in kinds]:
        fit, held = _cases(scenarios, kind, "identify"), _cases(scenarios, kind, "validate")
        # a fault drives the field voltage to its ceiling: fitted only where a limit is (see the module)
        faults = _cases(scenarios, kind, "identify", ("fault",)) if kind == "exciter" else []
        if not fit and kind == "stabiliser":
            from phid_ros.controls.stabiliser_effect import stabiliser_from_effect

            effect = stabiliser_from_effect(scenarios, out.get("exciter"), (candidates or {}).get(kind))
            if effect is not None:
                out[kind] = effect
                continue
        if not fit:
            out[kind] = f"not identified: no scenario with {' and '.join(KINDS[kind][0])} to fit"
            continue
        judge = held or fit  # without validation scenarios the fit's own error decides
        none = _rmse(judge, _no_control(judge))
        noise = _output_noise(judge)
        if NAMED_BELOW * none <= noise:
            # no model errs less than the output's own noise: none can be named, none is fitted
            out[kind] = (
                f"not named: beyond its reference steps the {KINDS[kind][1]} moves {none:.4g} pu rms, within "
                f"{1 / NAMED_BELOW:.3g} x its noise ({noise:.4g} pu): the recordings do not show the {kind}"
            )
            continue
        allowed = (candidates or {}).get(kind)
        models = [m for m in of_kind(kind) if allowed is None or m.name in allowed]
        # a model that reads a channel some identification scenario lacks cannot be fitted there
        # (PSS2A without the rotor speed): the others compete
        fitted_on = [s for s in scenarios if s.role == "identify"]
        unreadable = [m.name for m in models if not all(s.has(*m.needs) for s in fitted_on)]
        models = [m for m in models if m.name not in unreadable]
        if not models:
            lacking = f" ({', '.join(unreadable)} need channels not recorded)" if unreadable else ""
            out[kind] = f"not identified: no {kind} model among the candidates {sorted(allowed or [])}{lacking}"
            continue
        fits: list[ControlFit] = []
        for m in models:  # in registration order: a model may start where a simpler one ended
            earlier = {f.model: {k: v for k, v in f.parameters.items() if v is not None} for f in fits}
            given = (starts or {}).get(kind)
            own = dict(given) if given and set(given) >= {p.name for p in m.fitted()} else None
            limited = _with_reached_limits(
                m, fit_model(m, fit, held, earlier, checked=False, start_at=own), fit, faults, held
            )
            fits.append(_on_step_tests(m, limited, fit, held))
        chosen, alike = _simplest_best(fits)
        if _judged(chosen) < NAMED_BELOW * none:
            # the limits as the fit with the faults found them; the small-signal constants fitted
            # and checked on the small-signal tests, played through those limits (a fault's
            # switching, which the smoothed inputs blur, would weigh in every constant's profile)
            model = _without_unseen_terms(MODELS[chosen.model], chosen, fit, held)
            best = _refit_through_limits(model, chosen, fit, held, checked=True)
            for n in _limit_values(chosen):
                best.parameters[n], best.uncertainty[n] = chosen.parameters[n], chosen.uncertainty[n]
                best.identifiable[n] = chosen.identifiable[n]
            best.limits = chosen.limits
            best.pressed = sorted({*best.pressed, *(n for n in chosen.pressed if n in _limit_values(chosen))})
        else:  # no model is named: none of its constants is given as determined, and none is checked
            best = chosen
            best.identifiable = dict.fromkeys(best.identifiable, False)
        best.seen = limits_seen(MODELS[best.model], [*fit, *faults, *held], best.limits)
        best.alternatives = {f.model: _judged(f) for f in alike}
        err = _judged(best)
        best.none_heldout_rmse = none
        best.named = bool(err < NAMED_BELOW * none)
        judged_on = "held-out" if best.heldout_rmse is not None else "fit (no validation scenarios)"
        best.why = f"{best.model}: {judged_on} error {err:.4g} pu against {none:.4g} pu without control action" + (
            "" if best.named else f" (named below {NAMED_BELOW:g} of it: the recordings do not show the {kind})"
        )
        if best.named and alike:
            best.why += (
                f"; {', '.join(best.alternatives)} answer the recordings as well (within {SIMPLEST_WITHIN - 1:.0%}):"
                f" the simplest is named; name the unit's own with --{kind} MODEL"
            )
        if best.named and best.pressed:
            # the data push the limit where they say it cannot be: the model lacks what set it (a
            # constant ceiling asked to be both a no-load step's top and a loaded step's, which a
            # V_T- and I_FD-dependent one is); said, with the alike models that keep theirs inside
            inside = [f.model for f in alike if not f.pressed]
            best.why += f"; its {', '.join(best.pressed)} pressed on an end of its range (flagged)" + (
                f"; inside in {', '.join(inside)}" if inside else ""
            )
        out[kind] = best
    return out
