"""What a recording's channels determine, and the identification of what they do.

Fault recorders, relays, PMUs and excitation controllers record the terminal quantities and
rarely more: a MOD-026 voltage-step test carries V_t, I_t, P, Q and E_fd; a PMU export V and I
phasors; a no-load test V_t and E_fd. Each way to a parameter is a :class:`Route`: the recorded
channels it reads, the held values it needs, and what it assumes. :func:`plan` picks, for each
parameter, the first route the scenarios allow (in the order below: the paper's stages on the
full channel set first), or says what is missing, and :func:`identify_by_channels` runs the plan.
A parameter no route reaches is reported "not identifiable from these channels (needs ...)",
never as a number.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from phid_ros.errors import StageError
from phid_ros.ident import field_circuit, open_circuit, open_circuit_curve, stage1, stage2, stage3, terminal
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import ScenarioData, file_of
from phid_ros.model.parameters import PARAMETER_NAMES

if TYPE_CHECKING:
    from phid_ros.ident.pipeline import IdentificationResult, IdentifyOptions

ANGLE = ("v_t", "theta_t", "delta", "i_d", "i_q")  # the rotor angle and the currents in its frame
TERMINAL = ("v_t", "p_e", "q_e")


@dataclass(frozen=True)
class Route:
    key: str
    parameters: tuple[str, ...]
    channels: tuple[str, ...]  # recorded in the scenarios it uses
    how: str
    held: tuple[str, ...] = ()  # parameters the user must hold (--fix)
    no_load: bool = False  # uses no-load tests (no stator current)
    loaded: bool = False  # uses tests under load

    def scenarios(self, scs: Sequence[ScenarioData]) -> list[ScenarioData]:
        out = [s for s in scs if s.has(*self.channels)]
        if "theta_t" in self.channels:  # an angle recorded as 0 throughout is the reference, not a measurement
            out = [s for s in out if float(np.ptp(s["theta_t"])) > 0]
        if self.no_load:
            out = [s for s in out if terminal.at_no_load(s)]
        if self.loaded:
            out = [s for s in out if not terminal.at_no_load(s)]
        return out


ROUTES: tuple[Route, ...] = (
    Route("swing", ("H", "D"), ("omega", "p_m", "p_e"), "stage 1: the swing equation"),
    Route(
        "swing_constant_pm",
        ("H", "D"),
        ("omega", "p_e"),
        "stage 1 with P_m taken constant between steps (P_m not recorded)",
    ),
    Route(
        "swing_reconstructed",
        ("H", "D"),
        ("v_t", "theta_t", "p_e", "q_e"),
        "stage 1 on the rotor speed reconstructed from V and I with X_q held (and X'_q, T'_q0 for a round "
        "rotor), P_m constant between steps",
        held=("X_q",),
        loaded=True,
    ),
    Route("steady_states", ("X_d", "X_q"), (*ANGLE, "v_f"), "stage 2: the steady states"),
    Route(
        "steady_states_paper",
        ("X_d", "X_q"),
        ANGLE,
        "stage 2 by the paper's (37): X_d from several operating points without E_fd",
    ),
    Route(
        "field_circuit_online",
        ("X_d", "X_d_prime"),
        (*TERMINAL, "v_f", "i_fd"),
        "the field circuit on line: E'_q's course from E_fd - X_ad I_fd (T'_d0 from no load), the rotor angle "
        "reconstructed with X_q; X_d from the field current",
        held=("X_q",),
        loaded=True,
    ),
    Route(
        "steady_terminal",
        ("X_d",),
        (*TERMINAL, "v_f"),
        "the steady states of V_t, P, Q and E_fd, the rotor angle reconstructed with X_q",
        loaded=True,
    ),
    Route("d_axis", ("X_d_prime", "T_d0_prime"), (*ANGLE, "v_f"), "stage 3, d axis"),
    Route(
        "d_axis_terminal",
        ("X_d_prime", "T_d0_prime"),
        (*TERMINAL, "v_f"),
        "stage 3's d axis on the rotor angle reconstructed from V_t, P, Q",
        loaded=True,
    ),
    Route(
        "field_circuit",
        ("T_d0_prime",),
        ("v_t", "v_f", "i_fd"),
        "no-load events: the field circuit, E_fd - X_ad I_fd integrated per V_t moved",
        no_load=True,
    ),
    Route(
        "open_circuit",
        ("T_d0_prime",),
        ("v_t", "v_f"),
        "no-load field steps: V_t follows E_fd through T'_d0",
        no_load=True,
    ),
    Route("q_axis", ("X_q_prime", "T_q0_prime"), ANGLE, "stage 3, q axis"),
)
ROUTES_BY_KEY = {r.key: r for r in ROUTES}
FIELD_CURRENT_HOWS = {ROUTES_BY_KEY[k].how for k in ("field_circuit", "field_circuit_online")}


@dataclass(frozen=True)
class Planned:
    parameter: str
    route: Route | None
    needs: str  # what would make it determinable when route is None


def _needs(parameter: str, held: Mapping[str, float]) -> str:
    """What the user would add to determine ``parameter``: the channels of its routes."""
    wanted = []
    for r in ROUTES:
        if parameter in r.parameters:
            parts = [c for c in r.channels]
            parts += [f"--fix {h}" for h in r.held if h not in held]
            if r.no_load:
                parts.append("at no load")
            wanted.append(" + ".join(parts))
    return " or ".join(dict.fromkeys(wanted))


def _plan(usable: Callable[[Route], bool], held: Mapping[str, float]) -> list[Planned]:
    out = []
    for name in PARAMETER_NAMES:
        if name in held:
            out.append(Planned(name, None, "held (--fix)"))
            continue
        chosen = next(
            (r for r in ROUTES if name in r.parameters and all(h in held for h in r.held) and usable(r)), None
        )
        out.append(Planned(name, chosen, "" if chosen else _needs(name, held)))
    return out


def plan(scenarios: Sequence[ScenarioData], held: Mapping[str, float]) -> list[Planned]:
    """For each parameter, the first route its scenarios' channels and held values allow (in ROUTES order)."""
    ident = [s for s in scenarios if s.role == "identify"]
    return _plan(lambda r: bool(r.scenarios(ident)), held)


def plan_for_channels(
    recorded: set[str], held: Mapping[str, float], *, no_load: bool = True, loaded: bool = True
) -> list[Planned]:
    """The plan from a recording's channel set alone (``phid info``): whether its tests are at
    no load or under load is taken from the caller (both possible unless it knows)."""
    return _plan(
        lambda r: set(r.channels) <= recorded and (no_load or not r.no_load) and (loaded or not r.loaded), held
    )


def full_channels(scenarios: Sequence[ScenarioData]) -> bool:
    """Whether every identification scenario carries every channel (the paper's three stages)."""
    return all(not s.absent for s in scenarios if s.role == "identify")


def not_determined(name: str, needs: str) -> Estimate:
    return Estimate(
        math.nan, math.nan, identifiable=False, note=f"{name}: not identifiable from these channels (needs {needs})"
    )


Say = Callable[[str], None]


def identify_by_channels(
    res: IdentificationResult, ident: list[ScenarioData], opt: IdentifyOptions, say: Say
) -> dict[str, str]:
    """Run the plan on scenarios that lack channels; returns parameter -> how it was determined."""
    run = _ChannelRun(res, ident, opt, say)
    run.swing()
    on_line = run.reactances()
    known = run.known_reactances()  # as the steady states gave them, before the d axis's checks
    run.d_axis(on_line, known)
    run.q_axis(known)
    run.not_determined_said()
    return run.how


class _ChannelRun:
    """One run of the plan: the result written as each route runs, and how each parameter was
    determined. The steps run in the plan's order: H and D; X_d and X_q; the d axis's transient
    (T'_d0 from the no-load tests once, whichever step asks first); the q axis's."""

    def __init__(self, res: IdentificationResult, ident: list[ScenarioData], opt: IdentifyOptions, say: Say) -> None:
        self.res, self.ident, self.opt, self.say = res, ident, opt, say
        self.held = opt.constraints.fixed
        self.chosen = {p.parameter: p for p in plan(ident, self.held)}
        self.how: dict[str, str] = {}
        self.no_load_done = False
        self.x_q_for_angle: float | None = self.held.get("X_q")

    def route_of(self, *names: str) -> Route | None:
        routes = {self.chosen[n].route for n in names if self.chosen[n].route is not None}
        return routes.pop() if len(routes) == 1 else None

    def put(self, estimates: Mapping[str, Estimate], route: Route) -> None:
        for n, e in estimates.items():
            if n in route.parameters and n not in self.held:
                self.res.estimates[n] = e
                self.how[n] = route.how

    def swing(self) -> None:
        """H and D by stage 1, on the rotor speed as recorded or as reconstructed."""
        res, held, opt = self.res, self.held, self.opt
        r = self.route_of("H", "D")
        if r is None:
            return
        self.say(f"H, D: {r.how}")
        scs = r.scenarios(self.ident)
        if r.key == "swing_reconstructed":
            q = _held_q_transient(held)
            scs = [
                terminal.with_channels(
                    s,
                    {"omega": terminal.rotor_speed(s, held["X_q"], q, opt.f_nominal_hz)},
                    f"rotor speed from the rotor angle reconstructed with X_q = {held['X_q']:g} pu (held)"
                    + ("" if q is None else f", X'_q = {q[0]:g} pu, T'_q0 = {q[1]:g} s (held)"),
                )
                for s in scs
            ]
        try:
            out = stage1.swing_regression(scs, opt.stage1_cutoff_hz, opt.constraints)
            res.stage1 = out
            self.put({"H": out.H, "D": out.D}, r)
        except StageError as exc:
            res.problems.append(f"stage 1 (H, D) did not run: {exc}")

    def t_d0_at_no_load(self) -> None:
        """T'_d0 from the no-load tests, once: V_t's route, then the field circuit's where the field
        current is recorded (taken where identified, or where neither is)."""
        if self.no_load_done or "T_d0_prime" in self.held:
            return
        self.no_load_done = True
        res, ident = self.res, self.ident
        oc = ROUTES_BY_KEY["open_circuit"]
        if oc.scenarios(ident):
            self.say(f"T'_d0: {oc.how}")
            try:
                o = open_circuit.open_circuit(oc.scenarios(ident))
                res.problems.extend(o.problems)
                res.route_details["open_circuit"] = {
                    "T_d0_prime": o.T_d0_prime.value,
                    "T_d0_prime_std": o.T_d0_prime.std,
                    "field_gain": o.field_gain,  # V_t per unit E_fd at no load: 1 on the air-gap line
                    "scenarios": o.scenarios,
                    "rms_pu": o.rms_pu,
                }
                current = res.estimates.get("T_d0_prime")
                better = (
                    current is None
                    or not current.identifiable
                    or o.T_d0_prime.std / o.T_d0_prime.value < current.std / current.value
                )
                if (better and o.T_d0_prime.identifiable) or (
                    not o.T_d0_prime.identifiable and (current is None or not current.identifiable)
                ):
                    self.put({"T_d0_prime": o.T_d0_prime}, oc)  # withheld, with why: the user sees the route's figures
            except StageError as exc:
                res.problems.append(f"open circuit (T'_d0) did not run: {exc}")
        fc = ROUTES_BY_KEY["field_circuit"]
        if fc.scenarios(ident):
            self.say(f"T'_d0: {fc.how}")
            _field_circuit(res, fc, fc.scenarios(ident), self.opt, self.put)

    def reactances(self) -> bool:
        """X_d and X_q (or X_d alone) by the first route the plan allows; whether the field circuit
        on line ran (then X'_d is its, and T'_d0 the no-load tests')."""
        res, ident = self.res, self.ident
        r = self.chosen["X_d"].route
        on_line = (
            r is not None
            and r.key == "field_circuit_online"
            and _field_circuit_online(res, r, ident, self.opt, self.put, self.say, self.t_d0_at_no_load)
        )
        if r is not None and r.key == "field_circuit_online":
            # done; or, without a no-load test to give the field current's base, E_fd's steady states
            r = None if on_line else ROUTES_BY_KEY["steady_terminal"]
        if r is not None and r.key in ("steady_states", "steady_states_paper"):
            self.say(f"X_d, X_q: {r.how}")
            try:
                out2 = stage2.identify_reactances(r.scenarios(ident), use_field_voltage=r.key == "steady_states")
                res.stage2 = out2
                self.put({"X_d": out2.X_d, "X_q": out2.X_q}, r)
                res.problems.extend(f"stage 2: {p}" for p in out2.problems)
            except StageError as exc:
                res.problems.append(f"stage 2 (X_d, X_q) did not run: {exc}")
        elif r is not None:
            self.steady_terminal(r)
        return on_line

    def steady_terminal(self, r: Route) -> None:
        """X_d from the steady states of V_t, P, Q and E_fd; X_q, which they hardly depend on,
        withheld (the value they put it at reconstructs the rotor angle)."""
        res, held = self.res, self.held
        self.say(f"X_d: {r.how}")
        try:
            st = terminal.steady_reactances(r.scenarios(self.ident), held.get("X_q"))
        except StageError as exc:
            res.problems.append(f"X_d did not run: {exc}")
            return
        self.put({"X_d": st.X_d}, r)
        res.route_details["steady_terminal"] = {
            "X_q_used": st.X_q.value,
            "rms_pu": st.rms_pu,
            "steady_points": [pt.__dict__ for pt in st.points],
        }
        if "X_q" not in held:
            self.x_q_for_angle = st.X_q.value
            res.estimates["X_q"] = Estimate(
                math.nan,
                math.nan,
                identifiable=False,
                note=(
                    f"X_q: not identifiable from V_t, P, Q, E_fd (the steady states hardly depend on it; they "
                    f"put it at {st.X_q.value:.3g} pu, which the rotor angle's reconstruction used): hold a "
                    "datasheet value (--fix X_q=...) or record the rotor angle"
                ),
            )

    def known_reactances(self) -> dict[str, float]:
        known = {n: e.value for n, e in self.res.estimates.items() if n in ("X_d", "X_q") and math.isfinite(e.value)}
        known.update({n: v for n, v in self.held.items() if n in ("X_d", "X_q")})
        return known

    def d_axis(self, on_line: bool, known: Mapping[str, float]) -> None:
        """X'_d and T'_d0 by stage 3's d axis (on the recorded or reconstructed rotor angle), T'_d0
        from the no-load tests; what E_fd's level carries withheld where it is off the machine's base."""
        res, ident, opt = self.res, self.ident, self.opt
        # with the field circuit on line, X'_d is its and T'_d0 the no-load tests'
        r = None if on_line else self.route_of("X_d_prime", "T_d0_prime") or self.chosen["T_d0_prime"].route
        if r is not None and r.key == "d_axis" and "X_d" in known:
            self.say(f"X'_d, T'_d0: {r.how}")
            _one_axis(res, r, r.scenarios(ident), True, known["X_d"], opt, self.put)
        elif r is not None and r.key == "d_axis_terminal" and "X_d" in known and self.x_q_for_angle is not None:
            self.say(f"X'_d, T'_d0: {r.how}")
            _d_axis_terminal(res, r, r.scenarios(ident), known["X_d"], self.x_q_for_angle, opt, self.put)
        self.t_d0_at_no_load()
        oc = ROUTES_BY_KEY["open_circuit"]
        gain = res.route_details.get("open_circuit", {}).get("field_gain")
        off = field_base_off(gain) if gain is not None else None
        if off is not None:
            for name in ("X_d", "X_d_prime", "T_d0_prime"):
                e = res.estimates.get(name)
                # the no-load V_t route says it itself; the field circuit's routes read E_fd on the base
                # the field current gives
                if e is not None and self.how.get(name) not in FIELD_CURRENT_HOWS | {oc.how}:
                    e.disqualify(off)

    def q_axis(self, known: Mapping[str, float]) -> None:
        r = self.route_of("X_q_prime", "T_q0_prime")
        if r is not None and "X_q" in known:
            self.say(f"X'_q, T'_q0: {r.how}")
            _one_axis(self.res, r, r.scenarios(self.ident), False, known["X_q"], self.opt, self.put)

    def not_determined_said(self) -> None:
        """Every parameter no route gave, said with what would determine it."""
        for p in plan(self.ident, self.held):
            if p.parameter not in self.res.estimates and p.parameter not in self.held:
                needs = p.needs or f"what {p.route.how if p.route else 'its route'} needs, which did not run"
                self.res.estimates[p.parameter] = not_determined(p.parameter, needs)


# V_t per unit of E_fd at a no-load plateau is 1 on the air-gap line and 1/(1 + S) above it (S(1.0)
# of a hydro unit up to about 0.2): beyond this band the recorded E_fd is not on the machine's base
FIELD_GAIN_BAND = (0.75, 1.1)


def field_base_off(gain: float) -> str | None:
    """The note that withholds what E_fd's steady level carries (X_d from the steady states, the
    d axis it drives) when the no-load tests show E_fd on another base (an excitation controller's own)."""
    if FIELD_GAIN_BAND[0] <= gain <= FIELD_GAIN_BAND[1]:
        return None
    return (
        f"E_fd is not on the machine's base: at no load V_t settles at {gain:.3f} x the recorded E_fd (1 on the "
        "air-gap line, a little less when saturated); state the field's base in the map (v_f: {base: ...})"
    )


def _field_circuit(
    res: IdentificationResult,
    route: Route,
    scs: list[ScenarioData],
    opt: IdentifyOptions,
    put: Callable[[Mapping[str, Estimate], Route], None],
) -> None:
    """T'_d0 by the field circuit, in place of the terminal voltage's routes where it is
    identified (it reads neither the dampers' nor the saturation's dynamics, and the field base
    from the file's own plateaus), and where neither is."""
    try:
        f = field_circuit.field_circuit(scs, opt.constraints.saturation)
    except StageError as exc:
        res.problems.append(f"field circuit (T'_d0) did not run: {exc}")
        return
    res.route_details["field_circuit"] = {
        "T_d0_prime": f.T_d0_prime.value,
        "T_d0_prime_std": f.T_d0_prime.std,
        "field_current_base": f.base.scale,  # X_ad I_fd per unit of the recorded I_f (a bound if not determined)
        "field_current_base_determined": f.base.determined,
        "field_current_base_source": f.base.source,
        "events": [
            {"scenario": e.scenario, "delta_v": e.delta_v, "k_e": e.k_e, "T_d0_prime": f.base.scale * e.time_per_base}
            for e in f.events
        ],
        "plateaus": [{"v_t": v, "i_fd": i, "scenario": n} for v, i, n in f.plateaus],
        # the open-circuit curve's measured points on that base (empty where it is not determined)
        "saturation_at_plateaus": [{"v_t": v, "S": sat, "scenario": n} for v, sat, n in f.saturation_at_plateaus()],
        "build_ups": [
            {
                "scenario": b.scenario,
                "air_gap_line": b.c,  # V_t per unit of the recorded I_f
                "air_gap_line_rel_std": b.rel_std,
                "rotor_circuits_tau_s": b.tau,
                "rotor_circuits_t_s": b.t_k,
            }
            for b in f.build_ups
        ],
    }
    if f.leakage is not None:  # the field's leakage flux: the test files' T'_d0 against their dI/dV
        res.route_details["field_circuit"]["leakage"] = {
            "files": [{"file": n, "field_current_per_volt": r, "T_d0_prime": t} for n, r, t in f.leakage.per_volt],
            "T_leakage": f.leakage.leakage,
            "T_leakage_std": f.leakage.leakage_std,
            "T_d0_prime_unsaturated": f.leakage.unsaturated,
            "T_d0_prime_unsaturated_std": f.leakage.unsaturated_std,
            "shows": f.leakage.shows,
        }
    curve = open_circuit_curve.open_circuit_curve(f.base, scs, _air_gap_rel_std(f))
    if curve is not None:
        res.route_details["field_circuit"]["open_circuit_curve"] = curve.as_dict()
    current = res.estimates.get("T_d0_prime")
    if f.T_d0_prime.identifiable or current is None or not current.identifiable:
        put({"T_d0_prime": f.T_d0_prime}, route)


def _air_gap_rel_std(f: field_circuit.FieldCircuitResult) -> float:
    """The air-gap line's relative std where build-ups from standstill gave it (their root mean
    square), NaN otherwise."""
    lines = [line.rel_std for line in f.build_ups]
    return float(np.sqrt(np.mean(np.square(lines)))) if lines else math.nan


def impossible_field(route_details: Mapping[str, Any]) -> str:
    """Why the field's channels are not to be trusted, or "": the field circuit found a negative
    T'_d0 (overall or in a test), which no machine has. E_fd and I_fd exchanged in a map gave
    T'_d0 = -4.80 s and, from the same E_fd, an exciter published as determined; what a run fits
    from channels that gave an impossible value is withheld with this reason."""
    fc = route_details.get("field_circuit") or {}
    found = [("the tests together", fc.get("T_d0_prime"))]
    found += [(str(e.get("scenario")), e.get("T_d0_prime")) for e in fc.get("events", [])]
    bad = [(n, v) for n, v in found if isinstance(v, (int, float)) and math.isfinite(v) and v < 0]
    if not bad:
        return ""
    where = ", ".join(f"{v:.3g} s ({n})" for n, v in bad[:3])
    return (
        f"the field's channels gave T'_d0 = {where}, which no machine has: E_fd and I_fd exchanged, or a field "
        "channel mis-scaled, in the map?"
    )


def _field_circuit_online(
    res: IdentificationResult,
    route: Route,
    ident: list[ScenarioData],
    opt: IdentifyOptions,
    put: Callable[[Mapping[str, Estimate], Route], None],
    say: Say,
    t_d0_at_no_load: Callable[[], None],
) -> bool:
    """X_d and X'_d by the field circuit on line, T'_d0 first from the no-load tests (or held);
    False where the set has no no-load test to give the field current's base and T'_d0 (the
    caller takes E_fd's steady states then)."""
    held = opt.constraints.fixed
    field = field_circuit.machine_field(ident, opt.constraints.saturation)
    no_load = [s for s in ident if s.has("v_t", "v_f") and terminal.at_no_load(s)]
    if field is None or ("T_d0_prime" not in held and not no_load):
        return False
    say(f"X_d, X'_d: {route.how}")
    if "T_d0_prime" in held:
        t_d0 = Estimate(held["T_d0_prime"], 0.0)
    else:
        t_d0_at_no_load()
        t_d0 = res.estimates.get("T_d0_prime") or Estimate(math.nan, math.nan, identifiable=False)
    try:
        # the no-load files T'_d0 came from: each on-line file's T'_d0 is referred to its own field resistance
        files = [] if "T_d0_prime" in held else sorted({file_of(s) for s in no_load})
        out = field_circuit.on_line(
            route.scenarios(ident), field, t_d0, held["X_q"], opt.constraints.saturation, t_d0_files=files
        )
    except StageError as exc:
        res.problems.append(f"the field circuit on line (X_d, X'_d) did not run: {exc}")
        return False
    put({"X_d": out.X_d, "X_d_prime": out.X_d_prime}, route)
    res.route_details["field_circuit_online"] = {"events": out.events, "field_base_note": field.note}
    return True


def _one_axis(
    res: IdentificationResult,
    route: Route,
    scs: list[ScenarioData],
    d_axis: bool,
    x_sync: float,
    opt: IdentifyOptions,
    put: Callable[[Mapping[str, Estimate], Route], None],
) -> tuple[Estimate, Estimate] | None:
    names = ("X_d_prime", "T_d0_prime") if d_axis else ("X_q_prime", "T_q0_prime")
    try:
        x_prime, tau, _ = stage3.one_axis(stage3.prepare(scs, opt.prefilter_hz), d_axis, x_sync, opt.constraints)
    except StageError as exc:
        res.problems.append(f"stage 3 ({', '.join(names)}) did not run: {exc}")
        return None
    put(dict(zip(names, (x_prime, tau))), route)
    return x_prime, tau


def _held_q_transient(held: Mapping[str, float]) -> tuple[float, float] | None:
    """(X'_q, T'_q0) when the user holds both (a round rotor's datasheet), else None."""
    return (held["X_q_prime"], held["T_q0_prime"]) if "X_q_prime" in held and "T_q0_prime" in held else None


X_Q_ALLOWANCE = 0.10  # X_q from the steady states of V_t, P, Q, E_fd was off by up to 11 % (noiseless)


def _d_axis_terminal(
    res: IdentificationResult,
    route: Route,
    scs: list[ScenarioData],
    x_d: float,
    x_q: float,
    opt: IdentifyOptions,
    put: Callable[[Mapping[str, Estimate], Route], None],
) -> None:
    """X'_d and T'_d0 on the reconstructed rotor angle; without X_q held, their error bars carry
    what +-10 % of X_q does to them."""
    held = opt.constraints.fixed
    q = _held_q_transient(held)
    if q is not None:
        why = "held"
    else:
        search = terminal.q_axis_search(scs, x_q, x_d, opt.prefilter_hz)
        q = search.q_transient
        res.route_details["q_axis_search"] = {
            "X_q_prime": None if q is None else q[0],
            "T_q0_prime": None if q is None else q[1],
            "sse": search.sse,
            "sse_at_rest": search.sse_at_rest,
            "evaluations": search.evaluations,
        }
        why = "at rest" if q is None else f"X'_q = {q[0]:.3g} pu, T'_q0 = {q[1]:.3g} s by the d axis's residual"
    source = "held" if "X_q" in held else "the steady states"
    rebuilt = [terminal.with_rotor_angle(s, x_q, source, q) for s in scs]
    got = _one_axis(res, route, rebuilt, True, x_d, opt, put)
    if got is None:
        return
    for e in got:
        e.add_note(f"rotor angle reconstructed from V_t, P, Q with X_q = {x_q:.4g} pu ({source}); q axis {why}")
    if "X_q" in held:
        return
    spread = [0.0, 0.0]
    for f in (1.0 - X_Q_ALLOWANCE, 1.0 + X_Q_ALLOWANCE):
        q_f = None if q is None else (q[0] * f, q[1])
        alt = [terminal.with_rotor_angle(s, x_q * f, source, q_f) for s in scs]
        try:
            xp, tau, _ = stage3.one_axis(stage3.prepare(alt, opt.prefilter_hz), True, x_d, opt.constraints)
        except StageError:
            continue
        spread = [max(spread[0], abs(xp.value - got[0].value)), max(spread[1], abs(tau.value - got[1].value))]
    for e, s in zip(got, spread):
        e.std = math.hypot(e.std, s)
        if e.identifiable and e.std / abs(e.value) > 0.10:
            e.disqualify("not determined with X_q unknown: hold a datasheet X_q (--fix X_q=...)")
        else:
            e.add_note(f"std includes {s:.3g} for X_q +-{100 * X_Q_ALLOWANCE:g} %")


def describe_plan(planned: Sequence[Planned], done: Mapping[str, str] | None = None) -> list[tuple[str, str]]:
    """(parameter, how or what it needs) for the table identify and info print; ``done``: how
    each parameter was determined in the end (an identification's ``determined_by``)."""
    out = []
    for p in planned:
        if done and p.parameter in done:
            out.append((p.parameter, done[p.parameter]))
        elif p.route is not None:
            out.append((p.parameter, p.route.how))
        else:
            out.append((p.parameter, p.needs if p.needs == "held (--fix)" else f"needs {p.needs}"))
    return out
