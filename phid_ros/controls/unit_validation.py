"""MOD-026/027 validation: each recorded step or disturbance against the unit model played in.

The unit (machine, exciter, governor) is driven by the recording's network side, as the model
validation tools that MOD-026/027 reports rely on do it: the terminal voltage's magnitude and
angle as recorded (so no network model is assumed), the exciter by the recorded terminal
voltage, the governor by the recorded speed (a frequency play-in). A unit without an exciter
(governor) takes the recorded E_fd (P_m) instead. The machine is the fourth-order model of
:func:`phid_ros.ident.validation.play_in`, or the record's with its saturation and dampers; the
control models are their small-signal paths (:mod:`phid_ros.controls.models`), with the limits a
model simulates; a reference step the recording does not size is sized on the recorded output,
as identification does. Then, where the recording shows the network's reactance (or at no load),
the exciter's loop is closed through the machine (:mod:`phid_ros.controls.closed_loop`): V_t,
Q and E_fd as the unit makes them, V_t checked too.

Checked per scenario: MOD-026 (excitation) the reactive power Q and the field voltage E_fd;
MOD-027 (turbine-governor) the active power P and the mechanical power P_m. A channel passes
where the simulated response stays within its band of the recorded one over the whole window:
P and Q within 0.05 pu (the tolerance the paper quotes from WECC's guideline, the one
``phid identify`` checks), E_fd and P_m within 10 % of the recorded response's largest
deviation from its pre-event value, and never less than 0.01 pu nor than four standard deviations
of the difference before the event about its 0.5 s moving mean (the recorded input's noise,
through a regulator's gain, is not the model's error; a difference that drifts is); both
compared through the same zero-phase 10 Hz low-pass, which keeps the controls' response and
drops the sensors' noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.controls.cases import (
    KINDS,
    ControlCase,
    control_case,
    fit_stride,
    recorded_set_point,
    regulator_out_of_loop,
    switched_on,
    zero_phase,
)
from phid_ros.controls.closed_loop import ClosedLoop, LoopNotClosed, close_loop
from phid_ros.controls.models import MODELS, ControlInputs, ControlModel, LimitsError, OperatingLevels
from phid_ros.controls.play import limited_output, simulate_cases, simulate_references
from phid_ros.ident.field_circuit import ON_BASE
from phid_ros.ident.network_equivalent import thevenin_reactance
from phid_ros.ident.plant_playin import OPEN_BREAKER_X, BehindReactance, behind_reactance, open_circuit_voltage
from phid_ros.ident.plant_playin import play_in as plant_play_in
from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.terminal import at_no_load, with_channels, with_rotor_angle
from phid_ros.ident.validation import MOD026_TOLERANCE_PU, STEP_SECONDS, play_in, play_in_stride
from phid_ros.io.recording import STABILISER_ON
from phid_ros.model.parameters import PARAMETER_NAMES, GeneratorParameters
from phid_ros.numerics import interpolant
from phid_ros.sim.effects import PlantEffect

Array = NDArray[np.float64]

STANDARD_OF = {"exciter": "MOD-026", "governor": "MOD-027"}
OUTPUT_OF = {"MOD-026": "v_f", "MOD-027": "p_m"}  # the output of the control model each standard tests
RESPONSE_SHARE = 0.10  # an E_fd or P_m band: this share of the recorded response's largest deviation
RESPONSE_FLOOR_PU = 0.01  # and never narrower than this
NOISE_PEAKS = 4.0  # nor than this many stds of the pre-event difference (the inputs' noise through the model)
COMPARE_CUTOFF_HZ = 10.0
# channel: (standard, what it is, fixed band in pu or None for the response share)
CHANNELS: dict[str, tuple[str, str, float | None]] = {
    "q_e": ("MOD-026", "Q", MOD026_TOLERANCE_PU),
    "v_f": ("MOD-026", "E_fd", None),
    "p_e": ("MOD-027", "P", MOD026_TOLERANCE_PU),
    "p_m": ("MOD-027", "P_m", None),
    # at no load (breaker open) the machine's own terminal voltage, simulated on open circuit from
    # the played field: there is no P or Q to check
    "v_t": ("MOD-026", "V_t", None),
}
AT_NO_LOAD = ("v_t",)  # the channels a no-load test checks, in place of P and Q


@dataclass
class ChannelCheck:
    channel: str
    standard: str
    max_error: float  # pu, largest |simulated - recorded| over the window
    band: float  # pu
    passed: bool
    simulated_by: str  # the model that made the simulated trace

    def as_json(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass
class ScenarioCheck:
    scenario: str
    kind: str
    t: Array  # s, the play-in's grid
    recorded: dict[str, Array]
    simulated: dict[str, Array]
    checks: list[ChannelCheck]
    notes: list[str] = field(default_factory=list)
    # the control output's channel -> the model that made it, or "recorded" where it was played in
    made_by: dict[str, str] = field(default_factory=dict)
    loop_closed: bool = False  # the exciter's loop closed through the machine (else from the recorded V_t)

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)

    def exercised(self, standard: str) -> bool:
        """Whether this event tested the standard's control model: it was played in (not its
        output as recorded) and a channel of that standard was checked."""
        played = self.made_by.get(OUTPUT_OF[standard], "recorded") != "recorded"
        return played and any(c.standard == standard for c in self.checks)

    def as_json(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario,
            "kind": self.kind,
            "passed": self.passed,
            "checks": [c.as_json() for c in self.checks],
            "notes": self.notes,
        }


@dataclass
class UnitValidation:
    unit: str  # what was played in, one line
    scenarios: list[ScenarioCheck]
    notes: list[str]

    def passed(self, standard: str | None = None) -> bool:
        checks = [c for s in self.scenarios for c in s.checks if standard is None or c.standard == standard]
        return bool(checks) and all(c.passed for c in checks)

    def tested(self, standard: str) -> bool:
        """Whether any event tested the standard's control model (a unit without a governor, or
        with its P_m played as recorded, has its P checked, and MOD-027 is still not tested)."""
        return any(s.exercised(standard) for s in self.scenarios)

    def verdict(self, standard: str) -> bool | None:
        """The standard's verdict: passed or not, None where it was not tested (never "pass")."""
        return self.passed(standard) if self.tested(standard) else None

    def as_json(self) -> dict[str, Any]:
        return {
            "unit": self.unit,
            "mod026_pass": self.verdict("MOD-026"),
            "mod027_pass": self.verdict("MOD-027"),
            "tolerances": {
                "p_e, q_e": f"within {MOD026_TOLERANCE_PU:g} pu",
                "v_f, p_m": f"within {RESPONSE_SHARE:.0%} of the recorded response's largest deviation, at least "
                f"{RESPONSE_FLOOR_PU:g} pu ({COMPARE_CUTOFF_HZ:g} Hz zero-phase low-pass on both)",
                "left out": f"a fault's on-period and {SWITCH_CYCLES:g} cycles after each switching instant",
            },
            "scenarios": [s.as_json() for s in self.scenarios],
            "notes": self.notes,
        }


def field_on_machine_base(
    scenarios: Sequence[ScenarioData],
    open_circuit: Callable[[Array], Array],
    curve: str,
    saturation: tuple[float, float] | None = None,
) -> tuple[list[ScenarioData], list[str]]:
    """The recorded E_fd put on the machine's base where the recording's no-load tests show
    another (an excitation controller's own per unit: U_f 0.37 at V_t = 1.0), and the notes.

    Where the field current is recorded, file by file as identify does
    (:func:`phid_ros.ident.field_circuit.machine_field` on the record's curve, ``saturation``:
    its S(1.0), S(1.2)). Otherwise at a no-load plateau the machine's E_fd is
    ``open_circuit(V_t)``, the record's open-circuit curve (``curve`` says which): the recorded
    value's ratio to it, fitted through the origin over every plateau, is the base, applied to
    every scenario of the set (on line as well). Without a no-load test nothing is changed."""
    from phid_ros.ident.field_circuit import machine_field
    from phid_ros.ident.open_circuit import field_base

    by_current = machine_field(scenarios, saturation)
    if by_current is not None:
        if by_current.on_base():
            return list(scenarios), []
        note = f"{by_current.note} (the record's curve: {curve})"
        return by_current.applied(scenarios, note), [note]
    base = field_base(scenarios, open_circuit)
    if base is None or abs(base.scale - 1.0) <= ON_BASE:
        return list(scenarios), []
    k, v_t = base.scale, base.v_t
    note = (
        f"E_fd (v_f) is recorded on another base: 1 pu of the machine's = {1 / k:.4g} as recorded, from "
        f"{len(v_t)} no-load plateau(s) at V_t {v_t.min():.3f}-{v_t.max():.3f} pu on the record's open-circuit "
        f"curve ({curve}; points within {100 * base.scatter:.1f} %): every scenario's E_fd multiplied by {k:.4g}"
    )
    out = [with_channels(s, {"v_f": k * np.asarray(s["v_f"], float)}, note) if s.has("v_f") else s for s in scenarios]
    return out, [note]


@dataclass(frozen=True)
class Control:
    """A control model with its constants, as the unit carries it."""

    model: ControlModel
    values: dict[str, float]


def _with_stabiliser(s: ScenarioData, case: ControlCase, stabiliser: Control | None, notes: list[str]) -> ControlCase:
    """The exciter's case with the unit's stabiliser played in at its summing point, from the
    recorded P_e, where the recording shows the stabiliser on (its output recorded and moving:
    from where it started to) or the test sheet says so (``regulator: avr+pss``: from the start);
    the recorded output where the unit names none; otherwise as the case is (a stabiliser not
    known to be on is not played, and that is said)."""
    said_on = s.regulator == STABILISER_ON
    if not s.has("v_s") and not (said_on and stabiliser is not None):
        if stabiliser is not None:
            notes.append(f"stabiliser {stabiliser.model.name} not played in: the recording does not say it was on")
        elif said_on:
            notes.append("the stabiliser was on (the test sheet says), its output not recorded: no model to play")
        return case
    if stabiliser is None:
        notes.append("the recorded stabiliser output played in at the regulator's summing point")
        return case
    lacking = [c for c in stabiliser.model.needs if not s.has(c)]
    if lacking:
        notes.append(
            f"stabiliser {stabiliser.model.name} not played in: it reads {', '.join(lacking)}, not recorded"
            + ("; the recorded stabiliser output played in at the regulator's summing point" if s.has("v_s") else "")
        )
        return case
    # on from the start where the test sheet says it was on and its output is not recorded
    on = switched_on(s) if s.has("v_s") else 0
    x = case.inputs
    if on is None or x.p_e is None:
        notes.append(f"stabiliser {stabiliser.model.name} not played in: it was off (its output held still)")
        return replace(case, inputs=replace(x, v_s=np.zeros(len(x.v_t))))
    k_on = on // fit_stride(s.dt)
    after = np.arange(len(x.p_e)) >= k_on
    # the inputs from rest when switched on
    p_e, speed = (np.where(after, u - u[k_on], 0.0) for u in (x.p_e, x.speed))
    v_s = stabiliser.model.response(stabiliser.values, replace(x, p_e=p_e, speed=speed), 0.0)
    bounds = stabiliser.model.output_limits
    lo, hi = (stabiliser.values.get(n) for n in bounds) if bounds else (None, None)
    if lo is not None and hi is not None:
        v_s = np.clip(v_s, lo, hi)
    read = "rotor speed and P_e" if "omega" in stabiliser.model.needs else "P_e"
    # its own output against the recorded one: behind a regulator of high DC gain played from the
    # recorded V_t (no network closes its loop) a thousandth of a pu held for seconds is tenths of
    # E_fd (Mostar's return with the PSS on: Q 0.11 pu off with IEEEST, 0.03 with the recorded output)
    apart = float(np.max(np.abs(v_s[after] - x.v_s[after]))) if x.v_s is not None and after.any() else math.nan
    own = (
        f"; its output within {apart:.2g} pu of the recorded (which swung {float(np.ptp(x.v_s[after])):.2g})"
        if math.isfinite(apart) and x.v_s is not None
        else ""
    )
    said = "on throughout, as the test sheet says; its output not recorded"
    when = f"on from {on * s.dt:.1f} s" if s.has("v_s") else said
    notes.append(f"stabiliser {stabiliser.model.name} played in from the recorded {read} ({when}){own}")
    return replace(case, inputs=replace(x, v_s=v_s))


def _control_output(
    s: ScenarioData,
    kind: str,
    control: Control,
    level: float,
    notes: list[str],
    stabiliser: Control | None = None,
    reference: float | None = None,
    v_t_rest: float | None = None,
) -> tuple[Array, float] | None:
    """The control's output deviation (pu) on the scenario's samples, and the reference step it
    was given (``reference`` where given, else the test sheet's or sized); None where the
    recording lacks the input the kind needs. A model that simulates its limits
    (:meth:`ControlModel.limited`) is played from ``level``, its output's pre-event value, and its
    reference step sized by a bounded search (the response is not linear in it). An exciter's
    error takes the ``stabiliser`` (:func:`_with_stabiliser`); ``v_t_rest``: its set point, where
    not the scenario's pre-event V_t (:func:`~phid_ros.controls.cases.control_case`)."""
    case: ControlCase | None = control_case(s, kind, output=False, v_t_rest=v_t_rest)
    if case is None:
        return None
    if reference is not None and case.stepped:
        case = replace(case, reference=reference)
    if kind == "exciter":
        case = _with_stabiliser(s, case, stabiliser, notes)
    model, values = control.model, control.values
    v_t0 = float(np.mean(s["v_t"][s.pre_slice()])) if v_t_rest is None else v_t_rest
    levels = OperatingLevels(v_t0 + case.inputs.v_t, level, level) if kind == "exciter" else None
    try:
        limited = levels is not None and model.limited(values, case.inputs, 0.0, levels) is not None
    except LimitsError as exc:
        notes.append(f"{model.name}'s limits not simulated: {exc}")
        limited = False
    if limited:
        pred, reference = limited_output(model, values, replace(case, levels=levels))
    else:
        [pred] = simulate_cases(model, values, [case])
        [reference] = simulate_references(model, values, [case])
    k = fit_stride(s.dt)
    coarse = np.arange(0, s.n, k) * s.dt
    return interpolant(coarse, pred)(np.arange(s.n) * s.dt), reference


def _band(channel: str, recorded: Array, pre: slice) -> float:
    fixed = CHANNELS[channel][2]
    if fixed is not None:
        return fixed
    peak = float(np.max(np.abs(recorded - np.mean(recorded[pre])))) if recorded.size else 0.0
    return max(RESPONSE_FLOOR_PU, RESPONSE_SHARE * peak)


def _controls_played(
    s: ScenarioData, params: GeneratorParameters, controls: dict[str, Control]
) -> tuple[ScenarioData, dict[str, Array], dict[str, str], list[str], set[str], _Closing | None]:
    """The scenario as the unit sees it (its rotor angle reconstructed where not recorded), and
    what the unit's controls put in: (it, the channels played in, who made each, notes, the
    standards left unchecked, the exciter's loop to close or None)."""
    mine: list[str] = []
    unchecked: set[str] = set()
    if "delta" in s.absent or "i_d" in s.absent:
        s = with_rotor_angle(s, params.X_q, "the unit's X_q")
        mine.append("rotor angle reconstructed from V_t, P, Q with the unit's X_q")
    put: dict[str, Array] = {}
    by: dict[str, str] = {}
    closing: _Closing | None = None
    for kind, channel in (("exciter", "v_f"), ("governor", "p_m")):
        control = controls.get(kind)
        level = _pre_event_level(s, channel, params)
        if control is not None and kind == "exciter" and s.has("v_f") and (why := regulator_out_of_loop(s)):
            mine.append(f"exciter {control.model.name} not played in: {why}; E_fd as recorded")
            control = None
        stabiliser = controls.get("stabiliser")
        response = _control_output(s, kind, control, level, mine, stabiliser) if control is not None else None
        if control is not None and response is not None:
            put[channel], by[channel] = level + response[0], control.model.name
            if kind == "exciter":
                closing = _Closing(control, stabiliser, level, response[1])
            if kind == "exciter" and recorded_set_point(s) is not None:
                mine.append("exciter reference: the recorded set-point v_ref, as it moved")
            elif response[1]:
                said = s.reference_step is not None and s.kind in KINDS[kind].stepped
                how = "the test sheet's" if said else f"sized on the recorded {channel}"
                mine.append(f"{kind} reference step {response[1]:+.4g} ({how})")
        elif control is not None:
            mine.append(f"{kind} {control.model.name} not played in: the recording lacks {KINDS[kind].needs[0]}")
        given = kind == "exciter" and recorded_set_point(s) is not None
        if control is not None and s.kind in KINDS[kind].stepped and not s.has(channel) and not given:
            # a reference step of a size neither the recording nor the scenario gives: the unit
            # is not played through this test, and none of its channels says anything of the model
            unchecked.update(STANDARD_OF.values())
            mine.append(
                f"not checked: the {kind}'s reference step is sized on the recorded {channel}, which the "
                "recording lacks"
            )
        if channel not in put:
            if not s.has(channel):
                put[channel] = np.full(s.n, level)
                mine.append(f"{channel} not recorded: held at its pre-event value {level:.4g} pu")
            by.setdefault(channel, "recorded")
    if "omega" in s.absent:
        put["omega"] = np.ones(s.n)
    if "omega" in s.absent:
        put["omega"] = np.ones(s.n)
    return s, put, by, mine, unchecked, closing


def _checked(
    s: ScenarioData,
    p: ScenarioData,
    traj: _Played,
    by: dict[str, str],
    mine: list[str],
    unchecked: set[str],
    loop_run: BehindReactance | None,
    unit: tuple[dict[str, float], Sequence[tuple[type[PlantEffect], Mapping[str, Any]]], float],
) -> ScenarioCheck:
    """One scenario's checks: the recorded ``s`` against the unit's play-in (``p`` with the
    controls' outputs, ``traj`` the machine's P and Q, ``loop_run`` its V_t with the exciter's
    loop closed); ``unit``: (the base parameters, the effects simulated, the nominal frequency)."""
    base, kept, f_nominal_hz = unit
    idx = np.arange(0, s.n, play_in_stride(s.dt))
    pre = slice(0, max(1, int(np.searchsorted(idx, s.k_event))))
    skip = switching_spans(s, idx, f_nominal_hz)
    simulated = {"p_e": traj.p_e[:, 0], "q_e": traj.q_e[:, 0], "v_f": p["v_f"][idx], "p_m": p["p_m"][idx]}
    no_load = at_no_load(s)
    if loop_run is not None:
        simulated["v_t"] = np.interp(idx, loop_run.idx, loop_run.v_t)
    elif no_load:
        oc_idx, v_open = open_circuit_voltage(p, base, kept, f_nominal_hz, STEP_SECONDS)
        simulated["v_t"] = np.interp(idx, oc_idx, v_open)
    if no_load:
        mine.append("no load: the machine's V_t simulated on open circuit (no P, Q to check)")
    if not (np.isfinite(simulated["p_e"]).all() and np.isfinite(simulated["q_e"]).all()):
        mine.append("the machine's play-in diverged (not a number): every check of it fails")
    recorded: dict[str, Array] = {}
    checks: list[ChannelCheck] = []
    for channel, (standard, _label, _fixed) in CHANNELS.items():
        if not s.has(channel) or standard in unchecked:
            continue
        if channel in AT_NO_LOAD and "v_t" not in simulated:
            continue  # V_t is checked where the machine makes it: on open circuit, or with the loop closed
        if channel in ("p_e", "q_e") and no_load:
            continue  # no P, Q on open circuit
        if channel in ("v_f", "p_m") and by.get(channel) == "recorded":
            continue  # played in, not simulated: nothing to check
        full = np.asarray(p[channel], float) if channel in ("v_f", "p_m") else None
        if full is not None and channel == "v_f" and loop_run is not None:
            full = _from_recorded_rest(full, np.asarray(s[channel], float), s.pre_slice(), mine)
        sim_at = simulated[channel] if full is None else None
        check, rec_at, sim_at = channel_check(
            channel, np.asarray(s[channel], float), s.dt, idx, pre, full, sim_at, skip
        )
        check.simulated_by = by.get(channel, "machine")
        recorded[channel], simulated[channel] = rec_at, sim_at
        checks.append(check)
    t = np.asarray(idx * s.dt, float)
    return ScenarioCheck(s.name, s.kind, t, recorded, simulated, checks, mine, dict(by), loop_run is not None)


def validate_unit(
    scenarios: Sequence[ScenarioData],
    params: GeneratorParameters,
    controls: dict[str, Control],
    f_nominal_hz: float,
    describe: str,
    effects: Sequence[tuple[type[PlantEffect], Mapping[str, Any]]] = (),
    close_loops: bool = True,
) -> UnitValidation:
    """Every scenario played in with the unit; the MOD-026/027 checks and the traces for the
    overlays. ``effects``: the machine beyond the fourth-order model (a record's saturation and
    dampers), played in by the plant's own equations (:mod:`phid_ros.ident.plant_playin`).
    ``close_loops``: the exciter's loop closed through the machine where the recording allows
    (:func:`_closed_loop`); else every exciter is driven by the recorded V_t."""
    notes: list[str] = []
    played: list[ScenarioData] = []
    made: list[dict[str, str]] = []
    per_notes: list[list[str]] = []
    skipped: list[set[str]] = []
    seen: list[ScenarioData] = []  # each scenario as the unit sees it (its rotor angle reconstructed)
    closings: list[_Closing | None] = []
    for s in scenarios:
        s, put, by, mine, unchecked, closing = _controls_played(s, params, controls)
        played.append(with_channels(s, put, "the unit's control outputs played in") if put else s)
        made.append(by)
        per_notes.append(mine)
        skipped.append(unchecked)
        seen.append(s)
        closings.append(closing)
    kept = _simulable(effects, play_in_stride(played[0].dt) * played[0].dt, notes) if played else []
    trajectories = _machine_play_in(played, params, f_nominal_hz, kept) if played else []
    base = {name: getattr(params, name) for name in PARAMETER_NAMES}
    closed_v: list[BehindReactance | None] = [None] * len(played)
    for i, closing in enumerate(closings):
        if closing is not None and not close_loops:
            per_notes[i].append("the exciter played from the recorded V_t, its loop open (as asked)")
        elif closing is not None:
            loop = _closed_loop(seen[i], played[i], closing, base, kept, f_nominal_hz, per_notes[i])
            if loop is not None:
                played[i] = with_channels(played[i], {"v_f": loop.v_f}, "E_fd with the exciter's loop closed")
                trajectories[i] = _Played(loop.run.p_e[:, None], loop.run.q_e[:, None])
                closed_v[i] = loop.run
    out: list[ScenarioCheck] = []
    for s, p, traj, by, mine, unchecked, loop_run in zip(
        scenarios, played, trajectories, made, per_notes, skipped, closed_v
    ):
        out.append(_checked(s, p, traj, by, mine, unchecked, loop_run, (base, kept, f_nominal_hz)))
    if not any(sc.checks for sc in out):
        notes.append("no channel to check: the recordings carry none of P, Q, E_fd, P_m")
    return UnitValidation(describe, out, notes)


@dataclass
class _Played:
    p_e: Array  # (steps, 1)
    q_e: Array


@dataclass
class _Closing:
    """What the exciter of a scenario was played with, to play it again in a closed loop."""

    control: Control
    stabiliser: Control | None
    level: float  # E_fd before the event
    reference: float  # the reference step it was given


def _from_recorded_rest(simulated: Array, recorded: Array, pre: slice, notes: list[str]) -> Array:
    """A closed loop's E_fd, moved to start where the recorded one does: the machine model's own
    field at the recorded operating point is not the recorded field (the regulator trims E_fd to
    whatever holds the recorded V_t), and that offset, said in ``notes``, is a steady-state figure
    of the machine model; what MOD-026 compares is the response (its band is a share of the
    recorded response), as an open-loop play-in, which starts at the recorded field, does."""
    own, rest = float(np.mean(simulated[pre])), float(np.mean(recorded[pre]))
    notes.append(
        f"E_fd at rest with the loop closed: {own:.4g} pu against the recorded {rest:.4g} ({own - rest:+.3g} pu, "
        f"{(own - rest) / rest:+.1%}: the machine model's own field at the recorded operating point); the "
        "response compared from the recorded rest"
    )
    return simulated - (own - rest)


def exciter_step_response(control: Control, s: ScenarioData) -> Array:
    """The exciter's small-signal E_fd (pu) after a unit step of V_t at the scenario's first sample,
    on every sample (limits left out): the linear part of its loop."""
    k = fit_stride(s.dt)
    coarse = np.arange(0, s.n, k)
    zero = np.zeros(len(coarse))
    x = ControlInputs(s.dt * k, np.ones(len(coarse)), zero, zero)
    return np.interp(np.arange(s.n), coarse, control.model.response(control.values, x, 0.0))


def _closed_loop(
    s: ScenarioData,
    played: ScenarioData,
    closing: _Closing,
    base: Mapping[str, Any],
    effects: Sequence[tuple[type[PlantEffect], Mapping[str, Any]]],
    f_nominal_hz: float,
    notes: list[str],
) -> ClosedLoop | None:
    """The scenario with the exciter's loop closed through the machine (:mod:`phid_ros.controls.closed_loop`),
    behind the network the recording shows, or on open circuit at no load; None (said in
    ``notes``) where the network is not determined or the loop does not settle, and the exciter
    stays played from the recorded V_t."""
    if at_no_load(s):
        x_series, where = OPEN_BREAKER_X, "on open circuit"
    else:
        network = thevenin_reactance(s)
        if network is None:
            notes.append(
                "the exciter played from the recorded V_t (its loop open): the recording does not determine the "
                "network's reactance (V_t did not move with Q / V_t)"
            )
            return None
        x_series, where = network.x_e, f"behind {network.describe()}"
    said: list[str] = []  # the open-loop play-in said these already
    # the regulator holds the recorded V_t at rest: a machine that makes another V_t for the
    # recorded field is corrected by it, as the unit would be, and its field shows the difference
    set_point = float(np.mean(s["v_t"][s.pre_slice()]))

    def exciter(v_t: Array) -> Array:
        heard = with_channels(s, {"v_t": v_t}, "V_t as the closed loop makes it")
        out = _control_output(
            heard, "exciter", closing.control, closing.level, said, closing.stabiliser, closing.reference, set_point
        )
        if out is None or not np.isfinite(out[0]).all():
            # the loop's V_t left what the exciter can take (a record whose T_R 1e-9 s beside
            # T_C1 = T_B1 = 1e6 s made it diverge): no closed loop, not a traceback
            raise LoopNotClosed("the closed loop's V_t diverged")
        return closing.level + out[0]

    def machine(fields: list[Array]) -> list[BehindReactance]:
        columns = [with_channels(played, {"v_f": e}, "E_fd as the exciter makes it") for e in fields]
        return behind_reactance(columns, x_series, base, effects, f_nominal_hz, STEP_SECONDS)

    try:
        loop = close_loop(np.asarray(s["v_t"], float), exciter, exciter_step_response(closing.control, s), machine)
    except LoopNotClosed as exc:
        notes.append(f"{exc}: the exciter played from the recorded V_t (its loop open)")
        return None
    notes.append(
        f"the exciter's loop closed through the machine {where}: V_t, Q and E_fd as the unit makes them "
        f"({loop.iterations} iterations to |V - F(V)| {loop.residual:.1g} pu)"
    )
    return loop


def _simulable(
    effects: Sequence[tuple[type[PlantEffect], Mapping[str, Any]]], h: float, notes: list[str]
) -> list[tuple[type[PlantEffect], Mapping[str, Any]]]:
    """The effects the play-in's step ``h`` can integrate; one with a shorter time constant is left
    out, in ``notes``."""
    kept = []
    for cls, values in effects:
        short = {k: float(v) for k, v in values.items() if k.startswith("t_") and float(v) < MIN_STEPS_PER_CONSTANT * h}
        if short:
            named = ", ".join(f"{k} = {v:g} s" for k, v in short.items())
            notes.append(
                f"{cls.name} not simulated: {named} is shorter than {MIN_STEPS_PER_CONSTANT:g} play-in steps of "
                f"{h * 1e3:.3g} ms (the fourth-order machine instead)"
            )
            continue
        kept.append((cls, values))
    return kept


def _machine_play_in(
    played: Sequence[ScenarioData],
    params: GeneratorParameters,
    f_nominal_hz: float,
    effects: Sequence[tuple[type[PlantEffect], Mapping[str, Any]]],
) -> list[Any]:
    """The machine's P and Q at every play-in step: the fourth-order play-in, or the plant's with
    the effects (on the same grid: the validation's step)."""
    if not effects:
        return play_in(played, [params], f_nominal_hz)
    base = {name: getattr(params, name) for name in PARAMETER_NAMES}
    runs = plant_play_in(played, base, effects, 1, f_nominal_hz, step=STEP_SECONDS)
    return [_Played(r.sim["p_e"], r.sim["q_e"]) for r in runs]


def channel_check(
    channel: str,
    recorded: Array,
    dt: float,
    idx: NDArray[np.int64],
    pre: slice,
    simulated_full: Array | None = None,
    simulated_at: Array | None = None,
    left_out: NDArray[np.bool_] | None = None,
) -> tuple[ChannelCheck, Array, Array]:
    """One channel's check: the recorded samples against the simulated ones at ``idx`` (given
    there, or on every sample for the controls' outputs, which go through the comparison's
    low-pass as the recording does); ``pre`` the pre-event part of ``idx``; ``left_out``, the
    samples of ``idx`` not compared (:func:`switching_spans`). Returns the check and the two
    traces compared."""
    standard, _label, fixed = CHANNELS[channel]
    rec = recorded
    if simulated_full is not None:
        rec = zero_phase(recorded, dt, COMPARE_CUTOFF_HZ)
        sim = zero_phase(simulated_full, dt, COMPARE_CUTOFF_HZ)[idx]
    else:
        assert simulated_at is not None
        sim = simulated_at
    rec = rec[idx]
    compared = np.abs(sim - rec) if left_out is None else np.abs(sim - rec)[~left_out]
    err = float(np.max(compared)) if compared.size else 0.0
    if not np.isfinite(sim).all():
        err = math.inf  # a play-in that diverged fails, whatever the span compared
    band = _band(channel, rec, pre)
    if fixed is None and math.isfinite(err):  # what the recorded input's noise makes of the output
        step = float(idx[1] - idx[0]) * dt if len(idx) > 1 else dt
        with np.errstate(over="ignore", invalid="ignore"):  # a play-in of 1e200 pu: its noise is no band
            noise = _noise(sim[pre] - rec[pre], step)
        band = max(band, NOISE_PEAKS * noise) if math.isfinite(noise) else band
    return ChannelCheck(channel, standard, err, band, bool(err <= band), "machine"), rec, sim


SWITCH_CYCLES = 3.0  # cycles after each switching instant left out of the comparison
MIN_STEPS_PER_CONSTANT = 1.5  # RK4 diverges on a time constant shorter than about this many steps


def switching_spans(s: ScenarioData, idx: NDArray[np.int64], f_nominal_hz: float) -> NDArray[np.bool_]:
    """The samples of ``idx`` not compared: a fault's on-period and SWITCH_CYCLES cycles after
    each switching instant (a step, a fault's inception and clearing). A recorder's phasors smear
    a switch over their window, and the subtransient period, which a record's dampers and the
    fourth-order model draw differently, lasts a few cycles; MOD-026/027 judge the response."""
    t = idx * s.dt
    out = np.zeros(len(idx), dtype=bool)
    settle = SWITCH_CYCLES / f_nominal_hz
    for k in s.switching:
        out |= (t >= k * s.dt) & (t < k * s.dt + settle)
    if s.kind == "fault" and s.k_clear is not None:
        out |= (t >= s.k_event * s.dt) & (t < s.k_clear * s.dt)
    return out


NOISE_DETREND_S = 0.5  # the pre-event difference's noise: about its own 0.5 s moving mean


def _noise(d: Array, step_s: float) -> float:
    """The std of the pre-event difference about its moving mean: the recorded input's noise
    through the model. Not its plain std: a play-in that drifts away before the event (a model
    that diverges) widened the band with its own error, and a diverged run passed."""
    w = max(3, int(round(NOISE_DETREND_S / step_s)))
    if d.size < 2 * w:
        return float(np.std(d - np.mean(d))) if d.size else 0.0
    c = np.concatenate(([0.0], np.cumsum(d)))
    mean = (c[w:] - c[:-w]) / w
    return float(np.std(d[w // 2 : w // 2 + mean.size] - mean))


def _pre_event_level(s: ScenarioData, channel: str, params: GeneratorParameters) -> float:
    """A control output's pre-event value: as recorded, else where the machine held it: P_m at
    the pre-event P_e (no acceleration), E_fd at V_q + X_d I_d (equation (7) at rest)."""
    pre = s.pre_slice()
    if s.has(channel):
        return float(np.mean(s[channel][pre]))
    if channel == "p_m":
        return float(np.mean(s["p_e"][pre]))
    return float(np.mean(s.v_q[pre] + params.X_d * s["i_d"][pre]))


def control_of(model_name: str, values: dict[str, float]) -> Control:
    model = MODELS[model_name]
    return Control(model, model.recorded({**model.defaults(), **values}))
