"""A control system's recordings as its fit sees them: one case per scenario.

Each control system is the map from its recorded inputs to its recorded output, in deviations
from the steady state before each event: the exciter from (V_ref - V_t) to E_fd, the governor
from the speed deviation and load-reference steps to P_m, a stabiliser from the electrical
power to its recorded output. :class:`ControlKind` says, per kind, what it reads and which
scenarios it is fitted on.

Why the inputs are smoothed: the exciter's gain (~100) multiplies the PT's noise (0.002 pu)
into 0.2 pu on E_fd, which an output-error fit answers by lowering the gain; V_t and the speed
are low-passed forward and backward at 40 Hz (no lag). At 10 Hz the filter cut into the
exciter's own band: STEPS's SEXS gave T_E 0.0468 s for 0.05 (at 40 Hz 0.0495).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from phid_ros.controls.models import ControlInputs, OperatingLevels
from phid_ros.ident.scenario import ScenarioData
from phid_ros.io.recording import STABILISER_ON
from phid_ros.numerics import lowpass2

Array = NDArray[np.float64]

INPUT_CUTOFF_HZ = 40.0


# the fit's sample rate: the inputs are smoothed below 40 Hz, so 250 samples a second keep what
# they carry (Nyquist 125 Hz), and the feedback models' fits (IEEET1: ~1600 evaluations of 15
# scenarios) take seconds, not a minute, on 1 kHz recordings
FIT_RATE_HZ = 250.0


@dataclass(frozen=True)
class ControlKind:
    """What a kind of control system reads and is fitted on."""

    needs: tuple[str, ...]  # the channels it needs
    output: str  # its output channel
    stepped: tuple[str, ...]  # the scenario kinds with a reference step at the event
    fitted: tuple[str, ...]  # the scenario kinds it is fitted on


KINDS = {
    "exciter": ControlKind(("v_t", "v_f"), "v_f", ("field_step",), ("voltage_step", "torque_step", "field_step")),
    "governor": ControlKind(
        ("omega", "p_m"), "p_m", ("torque_step",), ("voltage_step", "torque_step", "field_step", "fault")
    ),
    # a stabiliser from its recorded output (a recorder's own channel) against the electrical power
    "stabiliser": ControlKind(("p_e", "v_s"), "v_s", (), ("voltage_step", "torque_step", "field_step")),
}

SWITCHED_OFF_S = 1.0  # a stabiliser output held at exactly one value this long: the stabiliser was off


EVENT_MARGIN_S = 0.05  # ... unless it starts to move this close to the event, or after: it answered the event


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


def cases_of(
    scenarios: Sequence[ScenarioData], kind: str, role: str, kinds: Sequence[str] | None = None
) -> list[ControlCase]:
    fitted_kinds = KINDS[kind].fitted
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
    needs, out_channel, stepped_kinds = KINDS[kind].needs, KINDS[kind].output, KINDS[kind].stepped
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


def no_control(cases: Sequence[ControlCase]) -> list[Array]:
    """The output held, but for each reference step (its size by least squares)."""
    out = []
    for c in cases:
        u = c.inputs.reference_step
        r = float(u @ c.output) / float(u @ u) if c.stepped else 0.0
        out.append(r * u)
    return out


def output_noise(cases: Sequence[ControlCase]) -> float:
    """The output's noise (pu rms) before the events: its sample-to-sample differences over sqrt(2),
    which a slow drift does not reach."""
    diffs = [np.diff(c.output[c.inputs.reference_step == 0]) for c in cases]
    d = np.concatenate([x for x in diffs if x.size]) if any(x.size for x in diffs) else np.zeros(0)
    return float(np.sqrt(np.mean(d**2) / 2.0)) if d.size else 0.0


def rmse(cases: Sequence[ControlCase], predicted: Sequence[Array]) -> float:
    err = np.concatenate([c.output - p for c, p in zip(cases, predicted)]) if cases else np.zeros(0)
    return float(np.sqrt(np.mean(err**2))) if err.size else math.nan
