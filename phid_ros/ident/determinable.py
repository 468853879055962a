"""What a recording's channels determine, and the identification of what they do.

Fault recorders, relays, PMUs and excitation controllers record the terminal quantities and
rarely more: a MOD-026 voltage-step test carries V_t, I_t, P, Q and E_fd; a PMU export V and I
phasors; a no-load test V_t and E_fd. Each way to a parameter is a :class:`~phid_ros.ident.routes.Route`:
the recorded channels it reads, the held values it needs, what it assumes, and what must run
before it (T'_d0 from the no-load tests before the field circuit on line). :func:`plan` picks, for
each parameter, the first route the scenarios allow (in :data:`ROUTES`' order), or says what is
missing; :func:`steps` orders the chosen routes and :func:`identify_by_channels` runs them
through :func:`~phid_ros.ident.routes.run_plan`, the loop the paper's stages run through on the
full channel set. A parameter no route reaches is reported "not identifiable from these channels
(needs ...)", never as a number.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from phid_ros.errors import StageError
from phid_ros.ident import field_circuit, open_circuit, open_circuit_curve, stage1, stage2, stage3, terminal
from phid_ros.ident.identification import IdentificationResult, IdentifyOptions, Say
from phid_ros.ident.results import Estimate
from phid_ros.ident.route_figures import (
    FieldCircuitFigures,
    FieldCircuitOnlineFigures,
    OpenCircuitFigures,
    QAxisSearchFigures,
    RouteFigures,
    SteadyTerminalFigures,
)
from phid_ros.ident.routes import Route, RouteOutput, RouteRun, run_plan
from phid_ros.ident.scenario import ScenarioData, file_of
from phid_ros.model.parameters import PARAMETER_NAMES

ANGLE = ("v_t", "theta_t", "delta", "i_d", "i_q")  # the rotor angle and the currents in its frame
TERMINAL = ("v_t", "p_e", "q_e")


class Swing(Route):
    """Stage 1: the swing equation on the recorded rotor speed."""

    key = "swing"
    parameters = ("H", "D")
    channels: ClassVar[tuple[str, ...]] = ("omega", "p_m", "p_e")
    how = "stage 1: the swing equation"
    says = "H, D"
    failed_as = "stage 1 (H, D)"
    result_as = "stage1"

    def speeds(self, run: RouteRun) -> list[ScenarioData]:
        return self.scenarios(run.ident)

    def run(self, run: RouteRun) -> RouteOutput:
        out = stage1.swing_regression(self.speeds(run), run.opt.stage1_cutoff_hz, run.opt.constraints)
        return RouteOutput({"H": out.H, "D": out.D}, stage_result=out)


class SwingConstantPm(Swing):
    key = "swing_constant_pm"
    channels = ("omega", "p_e")
    how = "stage 1 with P_m taken constant between steps (P_m not recorded)"


class SwingReconstructed(Swing):
    """Stage 1 on the rotor speed reconstructed from V and I with X_q held."""

    key = "swing_reconstructed"
    channels = ("v_t", "theta_t", "p_e", "q_e")
    how = (
        "stage 1 on the rotor speed reconstructed from V and I with X_q held (and X'_q, T'_q0 for a round "
        "rotor), P_m constant between steps"
    )
    held = ("X_q",)
    loaded = True

    def speeds(self, run: RouteRun) -> list[ScenarioData]:
        held, q = run.held, _held_q_transient(run.held)
        return [
            terminal.with_channels(
                s,
                {"omega": terminal.rotor_speed(s, held["X_q"], q, run.opt.f_nominal_hz)},
                f"rotor speed from the rotor angle reconstructed with X_q = {held['X_q']:g} pu (held)"
                + ("" if q is None else f", X'_q = {q[0]:g} pu, T'_q0 = {q[1]:g} s (held)"),
            )
            for s in self.scenarios(run.ident)
        ]


class SteadyStates(Route):
    """Stage 2: X_d and X_q from the steady states."""

    key = "steady_states"
    parameters = ("X_d", "X_q")
    channels: ClassVar[tuple[str, ...]] = (*ANGLE, "v_f")
    how = "stage 2: the steady states"
    says = "X_d, X_q"
    failed_as = "stage 2 (X_d, X_q)"
    result_as = "stage2"
    use_field_voltage = True

    def run(self, run: RouteRun) -> RouteOutput:
        out = stage2.identify_reactances(self.scenarios(run.ident), use_field_voltage=self.use_field_voltage)
        return RouteOutput(
            {"X_d": out.X_d, "X_q": out.X_q}, problems=[f"stage 2: {p}" for p in out.problems], stage_result=out
        )


class SteadyStatesPaper(SteadyStates):
    key = "steady_states_paper"
    channels = ANGLE
    how = "stage 2 by the paper's (37): X_d from several operating points without E_fd"
    use_field_voltage = False


class FieldCircuitOnline(Route):
    """X_d and X'_d by the field circuit on line, T'_d0 first from the no-load tests (or held);
    not ready where the set has no no-load test to give the field current's base and T'_d0
    (E_fd's steady states instead)."""

    key = "field_circuit_online"
    parameters = ("X_d", "X_d_prime")
    channels = (*TERMINAL, "v_f", "i_fd")
    how = (
        "the field circuit on line: E'_q's course from E_fd - X_ad I_fd (T'_d0 from no load), the rotor angle "
        "reconstructed with X_q; X_d from the field current"
    )
    held = ("X_q",)
    loaded = True
    first = ("open_circuit", "field_circuit")
    instead = "steady_terminal"
    says = "X_d, X'_d"
    failed_as = "the field circuit on line (X_d, X'_d)"

    def ready(self, run: RouteRun) -> bool:
        field = field_circuit.machine_field(run.ident, run.opt.constraints.saturation)
        run.cache["machine_field"] = field
        return field is not None and ("T_d0_prime" in run.held or bool(_no_load_field(run.ident)))

    def run(self, run: RouteRun) -> RouteOutput:
        held, field = run.held, run.cache["machine_field"]
        if "T_d0_prime" in held:
            t_d0 = Estimate(held["T_d0_prime"], 0.0)
        else:
            t_d0 = run.res.estimates.get("T_d0_prime") or Estimate(math.nan, math.nan, identifiable=False)
        # the no-load files T'_d0 came from: each on-line file's T'_d0 is referred to its own field resistance
        files = [] if "T_d0_prime" in held else sorted({file_of(s) for s in _no_load_field(run.ident)})
        out = field_circuit.on_line(
            self.scenarios(run.ident), field, t_d0, held["X_q"], run.opt.constraints.saturation, t_d0_files=files
        )
        return RouteOutput(
            {"X_d": out.X_d, "X_d_prime": out.X_d_prime},
            {self.key: FieldCircuitOnlineFigures(out.events, field.note)},
        )


def _no_load_field(ident: Sequence[ScenarioData]) -> list[ScenarioData]:
    return [s for s in ident if s.has("v_t", "v_f") and terminal.at_no_load(s)]


class SteadyTerminal(Route):
    """X_d from the steady states of V_t, P, Q and E_fd; X_q, which they hardly depend on,
    withheld (the value they put it at reconstructs the rotor angle)."""

    key = "steady_terminal"
    parameters = ("X_d",)
    channels = (*TERMINAL, "v_f")
    how = "the steady states of V_t, P, Q and E_fd, the rotor angle reconstructed with X_q"
    loaded = True
    says = "X_d"
    failed_as = "X_d"

    def run(self, run: RouteRun) -> RouteOutput:
        st = terminal.steady_reactances(self.scenarios(run.ident), run.held.get("X_q"))
        said = {}
        if "X_q" not in run.held:
            said["X_q"] = Estimate(
                math.nan,
                math.nan,
                identifiable=False,
                note=(
                    f"X_q: not identifiable from V_t, P, Q, E_fd (the steady states hardly depend on it; they "
                    f"put it at {st.X_q.value:.3g} pu, which the rotor angle's reconstruction used): hold a "
                    "datasheet value (--fix X_q=...) or record the rotor angle"
                ),
            )
        return RouteOutput({"X_d": st.X_d}, {self.key: SteadyTerminalFigures(st)}, said=said)


def x_q_for_angle(run: RouteRun) -> float | None:
    """The X_q the rotor angle is reconstructed with: held, or where E_fd's steady states put it."""
    if "X_q" in run.held:
        return run.held["X_q"]
    st = run.res.route_details.get("steady_terminal")
    return st.result.X_q.value if isinstance(st, SteadyTerminalFigures) else None


class DAxis(Route):
    """Stage 3's d axis on the recorded rotor angle; not with the field circuit on line (X'_d is
    its, T'_d0 the no-load tests')."""

    key = "d_axis"
    parameters = ("X_d_prime", "T_d0_prime")
    channels: ClassVar[tuple[str, ...]] = (*ANGLE, "v_f")
    how = "stage 3, d axis"
    says = "X'_d, T'_d0"
    failed_as = "stage 3 (X_d_prime, T_d0_prime)"

    def ready(self, run: RouteRun) -> bool:
        return "field_circuit_online" not in run.given and "X_d" in run.known("X_d")

    def run(self, run: RouteRun) -> RouteOutput:
        x_prime, tau = _one_axis(self.scenarios(run.ident), True, run.known("X_d")["X_d"], run.opt)
        return RouteOutput({"X_d_prime": x_prime, "T_d0_prime": tau})


class DAxisTerminal(DAxis):
    """X'_d and T'_d0 on the reconstructed rotor angle; without X_q held, their error bars carry
    what +-10 % of X_q does to them."""

    key = "d_axis_terminal"
    channels = (*TERMINAL, "v_f")
    how = "stage 3's d axis on the rotor angle reconstructed from V_t, P, Q"
    loaded = True

    def ready(self, run: RouteRun) -> bool:
        return super().ready(run) and x_q_for_angle(run) is not None

    def run(self, run: RouteRun) -> RouteOutput:
        x_q = x_q_for_angle(run)
        assert x_q is not None  # ready() saw it
        return _d_axis_terminal(self.scenarios(run.ident), run.known("X_d")["X_d"], x_q, run.opt)


class FieldCircuit(Route):
    """T'_d0 by the field circuit at no load, in place of the terminal voltage's routes where it
    is identified (it reads neither the dampers' nor the saturation's dynamics, and the field base
    from the file's own plateaus), and where neither is."""

    key = "field_circuit"
    parameters = ("T_d0_prime",)
    channels: ClassVar[tuple[str, ...]] = ("v_t", "v_f", "i_fd")
    how = "no-load events: the field circuit, E_fd - X_ad I_fd integrated per V_t moved"
    no_load = True
    says = "T'_d0"
    failed_as = "field circuit (T'_d0)"

    def ready(self, run: RouteRun) -> bool:
        return "T_d0_prime" not in run.held and bool(self.scenarios(run.ident))

    def run(self, run: RouteRun) -> RouteOutput:
        scs = self.scenarios(run.ident)
        f = field_circuit.field_circuit(scs, run.opt.constraints.saturation)
        curve = open_circuit_curve.open_circuit_curve(f.base, scs, _air_gap_rel_std(f))
        current = run.res.estimates.get("T_d0_prime")
        take = f.T_d0_prime.identifiable or current is None or not current.identifiable
        return RouteOutput({"T_d0_prime": f.T_d0_prime} if take else {}, {self.key: FieldCircuitFigures(f, curve)})


class OpenCircuit(FieldCircuit):
    """T'_d0 from no-load field steps (V_t following E_fd), taken where it is better than what
    the d axis gave, or where neither is identified (withheld, with why: the user sees its figures)."""

    key = "open_circuit"
    channels = ("v_t", "v_f")
    how = "no-load field steps: V_t follows E_fd through T'_d0"
    failed_as = "open circuit (T'_d0)"

    def run(self, run: RouteRun) -> RouteOutput:
        o = open_circuit.open_circuit(self.scenarios(run.ident))
        new, current = o.T_d0_prime, run.res.estimates.get("T_d0_prime")
        better = current is None or not current.identifiable or new.std / new.value < current.std / current.value
        take = (better and new.identifiable) or (not new.identifiable and (current is None or not current.identifiable))
        return RouteOutput({"T_d0_prime": new} if take else {}, {self.key: OpenCircuitFigures(o)}, list(o.problems))


class QAxis(Route):
    key = "q_axis"
    parameters = ("X_q_prime", "T_q0_prime")
    channels = ANGLE
    how = "stage 3, q axis"
    says = "X'_q, T'_q0"
    failed_as = "stage 3 (X_q_prime, T_q0_prime)"

    def ready(self, run: RouteRun) -> bool:
        return "X_q" in run.known("X_q")

    def run(self, run: RouteRun) -> RouteOutput:
        x_prime, tau = _one_axis(self.scenarios(run.ident), False, run.known("X_q")["X_q"], run.opt)
        return RouteOutput({"X_q_prime": x_prime, "T_q0_prime": tau})


# each parameter's routes in the order they are preferred: the paper's stages on the full channel set first
ROUTES: tuple[Route, ...] = (
    Swing(),
    SwingConstantPm(),
    SwingReconstructed(),
    SteadyStates(),
    SteadyStatesPaper(),
    FieldCircuitOnline(),
    SteadyTerminal(),
    DAxis(),
    DAxisTerminal(),
    FieldCircuit(),
    OpenCircuit(),
    QAxis(),
)
ROUTES_BY_KEY = {r.key: r for r in ROUTES}
FIELD_CURRENT_HOWS = {ROUTES_BY_KEY[k].how for k in ("field_circuit", "field_circuit_online")}


class FieldBaseCheck(Route):
    """Not a way to a parameter but the no-load tests' check on E_fd's base: where V_t settles
    off the air-gap line per unit of the recorded E_fd, what E_fd's level carries is withheld."""

    key = "field_base"
    parameters = ()
    how = "E_fd's base checked at no load"

    def run(self, run: RouteRun) -> RouteOutput:
        oc = run.res.route_details.get("open_circuit")
        off = field_base_off(oc.field_gain) if isinstance(oc, OpenCircuitFigures) else None
        if off is not None:
            for name in ("X_d", "X_d_prime", "T_d0_prime"):
                e = run.res.estimates.get(name)
                # the no-load V_t route says it itself; the field circuit's routes read E_fd on the base
                # the field current gives
                if e is not None and run.how.get(name) not in FIELD_CURRENT_HOWS | {ROUTES_BY_KEY["open_circuit"].how}:
                    e.disqualify(off)
        return RouteOutput()


FIELD_BASE_CHECK = FieldBaseCheck()
STEPS_BY_KEY: dict[str, Route] = {**ROUTES_BY_KEY, FIELD_BASE_CHECK.key: FIELD_BASE_CHECK}


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


def steps(ident: Sequence[ScenarioData], held: Mapping[str, float]) -> list[Route]:
    """The plan in the order its routes run: H and D; X_d and X_q; the d axis's transient, then
    T'_d0 from the no-load tests (once, whichever step asks first) and E_fd's base checked; the
    q axis's."""
    chosen = {p.parameter: p.route for p in plan(ident, held)}

    def common(*names: str) -> Route | None:
        routes = {chosen[n] for n in names if chosen[n] is not None}
        return routes.pop() if len(routes) == 1 else None

    d_axis = common("X_d_prime", "T_d0_prime") or chosen["T_d0_prime"]
    no_load = [ROUTES_BY_KEY["open_circuit"], ROUTES_BY_KEY["field_circuit"]]
    found = [
        common("H", "D"),
        chosen["X_d"],
        d_axis if isinstance(d_axis, DAxis) else None,
        *no_load,
        FIELD_BASE_CHECK,
        common("X_q_prime", "T_q0_prime"),
    ]
    return [r for r in found if r is not None]


def identify_by_channels(
    res: IdentificationResult, ident: list[ScenarioData], opt: IdentifyOptions, say: Say
) -> dict[str, str]:
    """Run the plan on scenarios that lack channels; returns parameter -> how it was determined."""
    run = RouteRun(res, ident, opt, say, STEPS_BY_KEY)
    run_plan(steps(ident, run.held), run)
    for p in plan(ident, run.held):  # every parameter no route gave, said with what would determine it
        if p.parameter not in res.estimates and p.parameter not in run.held:
            needs = p.needs or f"what {p.route.how if p.route else 'its route'} needs, which did not run"
            res.estimates[p.parameter] = not_determined(p.parameter, needs)
    return run.how


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


def _air_gap_rel_std(f: field_circuit.FieldCircuitResult) -> float:
    """The air-gap line's relative std where build-ups from standstill gave it (their root mean
    square), NaN otherwise."""
    lines = [line.rel_std for line in f.build_ups]
    return float(np.sqrt(np.mean(np.square(lines)))) if lines else math.nan


def impossible_field(route_details: Mapping[str, RouteFigures]) -> str:
    """Why the field's channels are not to be trusted, or "": the field circuit found a negative
    T'_d0 (overall or in a test), which no machine has. E_fd and I_fd exchanged in a map gave
    T'_d0 = -4.80 s and, from the same E_fd, an exciter published as determined; what a run fits
    from channels that gave an impossible value is withheld with this reason."""
    fc = route_details.get("field_circuit")
    if not isinstance(fc, FieldCircuitFigures):
        return ""
    found = [("the tests together", fc.T_d0_prime), *fc.t_d0_by_scenario().items()]
    bad = [(n, v) for n, v in found if math.isfinite(v) and v < 0]
    if not bad:
        return ""
    where = ", ".join(f"{v:.3g} s ({n})" for n, v in bad[:3])
    return (
        f"the field's channels gave T'_d0 = {where}, which no machine has: E_fd and I_fd exchanged, or a field "
        "channel mis-scaled, in the map?"
    )


def _one_axis(scs: list[ScenarioData], d_axis: bool, x_sync: float, opt: IdentifyOptions) -> tuple[Estimate, Estimate]:
    x_prime, tau, _ = stage3.one_axis(stage3.prepare(scs, opt.prefilter_hz), d_axis, x_sync, opt.constraints)
    return x_prime, tau


def _held_q_transient(held: Mapping[str, float]) -> tuple[float, float] | None:
    """(X'_q, T'_q0) when the user holds both (a round rotor's datasheet), else None."""
    return (held["X_q_prime"], held["T_q0_prime"]) if "X_q_prime" in held and "T_q0_prime" in held else None


X_Q_ALLOWANCE = 0.10  # X_q from the steady states of V_t, P, Q, E_fd was off by up to 11 % (noiseless)


def _d_axis_terminal(scs: list[ScenarioData], x_d: float, x_q: float, opt: IdentifyOptions) -> RouteOutput:
    held = opt.constraints.fixed
    q = _held_q_transient(held)
    figures: dict[str, RouteFigures] = {}
    if q is not None:
        why = "held"
    else:
        search = terminal.q_axis_search(scs, x_q, x_d, opt.prefilter_hz)
        q = search.q_transient
        figures["q_axis_search"] = QAxisSearchFigures(search)
        why = "at rest" if q is None else f"X'_q = {q[0]:.3g} pu, T'_q0 = {q[1]:.3g} s by the d axis's residual"
    source = "held" if "X_q" in held else "the steady states"
    rebuilt = [terminal.with_rotor_angle(s, x_q, source, q) for s in scs]
    try:
        got = _one_axis(rebuilt, True, x_d, opt)
    except StageError as exc:  # the q axis's search is kept: it says what the reconstruction tried
        return RouteOutput(figures=figures, problems=[f"{DAxisTerminal.failed_as} did not run: {exc}"])
    for e in got:
        e.add_note(f"rotor angle reconstructed from V_t, P, Q with X_q = {x_q:.4g} pu ({source}); q axis {why}")
    if "X_q" not in held:
        _x_q_spread(got, scs, x_d, x_q, q, source, opt)
    return RouteOutput({"X_d_prime": got[0], "T_d0_prime": got[1]}, figures)


def _x_q_spread(
    got: tuple[Estimate, Estimate],
    scs: list[ScenarioData],
    x_d: float,
    x_q: float,
    q: tuple[float, float] | None,
    source: str,
    opt: IdentifyOptions,
) -> None:
    """X'_d's and T'_d0's stds widened by what +-10 % of X_q moves them; withheld beyond 10 %."""
    spread = [0.0, 0.0]
    for f in (1.0 - X_Q_ALLOWANCE, 1.0 + X_Q_ALLOWANCE):
        q_f = None if q is None else (q[0] * f, q[1])
        alt = [terminal.with_rotor_angle(s, x_q * f, source, q_f) for s in scs]
        try:
            xp, tau = _one_axis(alt, True, x_d, opt)
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
