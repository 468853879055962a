"""T'_d0 from the field circuit at no load: what the recorded field current says beside V_t.

At no load the planning models' d axis (PSS/E's GENSAL and GENROU) reads

    T'_d0 dE'_q/dt = E_fd - X_ad I_fd,        E'_q = V_t at every steady state,

so over an event, from the plateau before it to the one after,

    T'_d0 (V_t1 - V_t0) = integral of (E_fd - X_ad I_fd) dt,

whatever the dampers and the regulator did in between (the dampers' currents start and end at
zero) and whatever the saturation (it lies in X_ad I_fd, which is measured, not modelled). An
excitation controller records both field channels on its own bases: X_ad I_fd = c I_f, and
E_fd = c k_e U_f, where k_e = I_f / U_f at the event's own plateaus (the field winding's
resistance at that test's temperature: on a real commissioning day U_f per I_f drifts by 14 %
between tests, I_f per V_t does not) and c is the field current's base,

    c = V_t (1 + S(V_t)) / I_f        at any no-load plateau (IEEE 115's air-gap line: S = 0).

c needs the open-circuit curve: it is determined when the plateaus lie on the air-gap line, or
from the machine's S(1.0), S(1.2) (its datasheet, held); when the plateaus are saturated and no
curve is given, S >= 0 still bounds c, and with it T'_d0, from below, which is said.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.integrate import cumulative_trapezoid

from phid_ros.errors import StageError
from phid_ros.ident.characteristics import LINEAR_PART
from phid_ros.ident.open_circuit import SATURATION_GAP
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import ScenarioData, file_of
from phid_ros.ident.terminal import at_no_load, with_channels, with_rotor_angle
from phid_ros.sim.effects.magnetic_saturation import no_load_field

MIN_VOLTAGE_CHANGE = 0.02  # pu of V_t between the plateaus: less carries too little of T'_d0
PLATEAU_FLOOR = 0.2  # pu of V_t: a de-excited machine's remanence is no point of the curve
LEAD_SECONDS = 0.5  # the integral starts this long before the event, on the plateau
FROM_SHARE = 1.0 / 3.0  # of V_t's change: from where the integral is fitted (the dampers settled)
SETTLED = 0.98  # of V_t's change: where the transient is over
TAIL_SECONDS = 1.0  # the fit goes on this long after it
ON_BASE = 0.05  # a recorded E_fd within this of the machine's base is taken as it is
FIELD_FLOOR = 0.05  # of U_f as recorded: a de-excited plateau says nothing of the winding's resistance


class FieldCircuitError(StageError):
    """No no-load event with V_t, E_fd and I_fd to integrate."""


@dataclass
class FieldCurrentBase:
    """The recorded I_f's base on the machine's: X_ad I_fd = ``scale`` x the recorded I_f."""

    scale: float  # c; for a lower bound only, the smallest c the plateaus allow
    determined: bool  # False: the plateaus are saturated and no curve was given (``scale`` a bound)
    source: str
    scatter: float  # the plateaus' largest relative distance from the curve used


MIN_PLATEAU_SPAN = 0.05  # pu of V_t: plateaus closer than this cannot show whether they bend


def field_current_base(
    v_t: Sequence[float],
    i_f: Sequence[float],
    saturation: tuple[float, float] | None,
    traversed: Sequence[tuple[float, str]] = (),
) -> FieldCurrentBase:
    """c from no-load plateaus (V_t, I_f as recorded): on the given curve (S(1.0), S(1.2), the
    quadratic form) or, without one, on the air-gap line traversed by a build-up from standstill
    (``traversed``: each one's c and scenario, :func:`build_up_line`), or on the air-gap line when
    plateaus spanning MIN_PLATEAU_SPAN agree within SATURATION_GAP in I_f per V_t; otherwise the
    bound S >= 0 gives. (Plateaus at one voltage agree with any curve: a single one at 1.0 pu was
    taken as on the air-gap line, and a saturated unit's T'_d0 published 10 % short.)"""
    v, i = np.asarray(v_t, float), np.asarray(i_f, float)
    if saturation is None and traversed:
        cs = np.array([c for c, _ in traversed])
        c = float(np.mean(cs))
        below = c * i / v - 1.0 < -SATURATION_GAP if len(v) else np.zeros(0, dtype=bool)
        if below.any():
            # saturation only ever raises the field current a voltage takes: a static point of the
            # same machine below the line says the rise's field current was not the curve's
            k = int(np.argmin(c * i / v))
            return FieldCurrentBase(
                float(np.min(v / i)),
                False,
                f"not determined: the no-load plateau at V_t {v[k]:.3f} pu lies {100 * (1 - c * i[k] / v[k]):.1f} % "
                "below the air-gap line the build-up(s) from standstill traversed "
                f"({', '.join(n for _, n in traversed)}), which no open-circuit curve allows",
                math.nan,
            )
        return FieldCurrentBase(
            c,
            True,
            f"the air-gap line the build-up(s) from standstill traversed ({', '.join(n for _, n in traversed)}; "
            f"V_t {LINEAR_PART[0]:g}-{LINEAR_PART[1]:g} pu against I_f)",
            float(np.max(np.abs(cs / c - 1.0))) if len(cs) > 1 else math.nan,
        )
    if saturation is not None:
        each = no_load_field(v, *saturation) / i
        c = float(np.mean(each))
        return FieldCurrentBase(
            c,
            True,
            f"the open-circuit curve S(1.0) = {saturation[0]:g}, S(1.2) = {saturation[1]:g} through "
            f"{len(v)} no-load plateau(s) at V_t {v.min():.3f}-{v.max():.3f} pu",
            float(np.max(np.abs(each / c - 1.0))),
        )
    per_volt = i / v
    linear = v <= LINEAR_PART[1]  # below the knee (IEEE 115's linear part): on the air-gap line
    spans = float(np.ptp(v)) >= MIN_PLATEAU_SPAN
    if (spans and per_volt.max() / per_volt.min() - 1.0 <= SATURATION_GAP) or linear.any():
        on_line = linear if linear.any() else np.ones(len(v), dtype=bool)
        c = float(np.mean(v[on_line] / i[on_line]))
        return FieldCurrentBase(
            c,
            True,
            f"the air-gap line through {int(on_line.sum())} no-load plateau(s) at V_t "
            f"{v[on_line].min():.3f}-{v[on_line].max():.3f} pu",
            float(np.max(np.abs(v[on_line] / i[on_line] / c - 1.0))),
        )
    k = int(np.argmin(per_volt))  # S >= 0: c is at least V_t / I_f at every plateau
    return FieldCurrentBase(
        float(v[k] / i[k]),
        False,
        f"not determined: the no-load plateaus are on the saturated part of the open-circuit curve (I_f per "
        f"V_t {per_volt.min():.4g} at {v[int(np.argmin(per_volt))]:.3f} pu, {per_volt.max():.4g} at "
        f"{v[int(np.argmax(per_volt))]:.3f} pu) and no plateau is on the air-gap line",
        math.nan,
    )


@dataclass
class FieldEvent:
    scenario: str
    before: tuple[float, float]  # (V_t, I_f as recorded) on the plateau before the event
    after: tuple[float, float]  # and after it
    delta_v: float  # V_t after minus before
    k_e: float  # the recorded I_f per U_f at this event's plateaus
    time_per_base: float  # integral / delta_v = T'_d0 / c
    # the recorded I_f moved per V_t over the same samples, as the fit weighs them (see FieldLeakage)
    current_per_volt: float = math.nan
    fit_share: float = math.nan  # the integral's misfit to T'_d0 x V_t moved, a share of T'_d0 (its largest)


@dataclass
class FieldLeakage:
    """What the events' T'_d0 say of the field's own leakage flux, which does not saturate.

    The field's flux is the air gap's (V_t at no load) and its leakage's (X_fl I_fd), so the
    integral per V_t moved is T_ad + T_fl dI/dV, dI/dV the field current (X_ad I_fd) moved per V_t
    over the samples the event's fit weighs: 1 on the air-gap line, more above the knee. GENSAL's
    and GENROU's form saturate the whole field flux with the air gap's and take one T'_d0: where
    the events' dI/dV differ and their T'_d0 rise with it, a line through the test files'
    (dI/dV, T'_d0) gives T_fl (its slope) and the unsaturated T'_d0 (IEEE 115's, a datasheet's:
    the line at dI/dV = 1)."""

    per_volt: list[tuple[str, float, float]]  # (file, dI/dV, T'_d0) of each test file's events
    leakage: float  # T_fl (s): the slope
    leakage_std: float  # from the files' scatter about the line (NaN without a file to spare)
    unsaturated: float  # T'_d0 at dI/dV = 1
    unsaturated_std: float
    shows: bool  # T_fl beyond LEAKAGE_STDS of its std and moving T'_d0 by LEAKAGE_SHARE across the files


@dataclass
class FieldCircuitResult:
    T_d0_prime: Estimate
    base: FieldCurrentBase
    events: list[FieldEvent]
    plateaus: list[tuple[float, float, str]]  # (V_t, I_f, scenario)
    leakage: FieldLeakage | None = None
    build_ups: list[BuildUpLine] = field(default_factory=list)  # the air-gap lines build-ups traversed

    def saturation_at_plateaus(self) -> list[tuple[float, float, str]]:
        """(V_t, S(V_t), scenario) at each no-load plateau on the field current's base: the
        open-circuit curve's measured points, S = X_ad I_fd / V_t - 1 (IEEE 115's, the planning
        models'), where the base is determined."""
        if not self.base.determined:
            return []
        return [(v, self.base.scale * i / v - 1.0, n) for v, i, n in self.plateaus]


LEAKAGE_SPREAD = 0.5  # of dI/dV between the test files: less cannot tell the leakage's share
LEAKAGE_STDS = 3.0  # T_fl beyond this many of its std
LEAKAGE_SHARE = 0.05  # and moving T'_d0 by this share across the files' dI/dV: less changes no study


def field_leakage(events: Sequence[FieldEvent], base: FieldCurrentBase) -> FieldLeakage | None:
    """The line through the test files' (dI/dV, T'_d0) (see :class:`FieldLeakage`); None where the
    files' dI/dV do not differ by LEAKAGE_SPREAD or fewer than two files have events."""
    files: dict[str, list[tuple[float, float]]] = {}
    for e in events:
        files.setdefault(file_of(e.scenario), []).append(
            (base.scale * e.current_per_volt, base.scale * e.time_per_base)
        )
    per = [(f, float(np.mean([p[0] for p in v])), float(np.mean([p[1] for p in v]))) for f, v in files.items()]
    r, t = np.array([p[1] for p in per]), np.array([p[2] for p in per])
    if len(per) < 2 or np.ptp(r) < LEAKAGE_SPREAD:
        return None
    design = np.column_stack([np.ones(len(r)), r - 1.0])
    coef, *_ = np.linalg.lstsq(design, t, rcond=None)
    spare = len(per) - 2
    sd = (math.nan, math.nan)
    if spare > 0:
        s2 = float(np.sum((t - design @ coef) ** 2)) / spare
        cov = s2 * np.linalg.inv(design.T @ design)
        sd = (float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1])))
    unsat, t_fl = float(coef[0]), float(coef[1])
    shows = bool(
        math.isfinite(sd[1]) and t_fl > LEAKAGE_STDS * sd[1] and t_fl * float(np.ptp(r)) > LEAKAGE_SHARE * unsat
    )
    return FieldLeakage(per, t_fl, sd[1], unsat, sd[0], shows)


def field_events(scenarios: Sequence[ScenarioData]) -> list[ScenarioData]:
    """The identification scenarios at no load with V_t, E_fd and I_fd whose V_t moves between plateaus."""
    out = []
    for s in scenarios:
        if s.role != "identify" or not s.has("v_t", "v_f", "i_fd") or not at_no_load(s):
            continue
        pre, post = s.pre_slice(), s.steady_slice()
        if len(s["v_t"][pre]) < 10 or len(s["v_t"][post]) < 10:
            continue
        if abs(float(np.mean(s["v_t"][post]) - np.mean(s["v_t"][pre]))) >= MIN_VOLTAGE_CHANGE:
            out.append(s)
    return out


def _plateau(s: ScenarioData, sl: slice) -> tuple[float, float, float]:
    return tuple(float(np.mean(s[c][sl])) for c in ("v_t", "v_f", "i_fd"))  # type: ignore[return-value]


def departure(s: ScenarioData) -> int:
    """The first sample at which V_t or I_f leaves the level it held at the window's start: a
    de-excitation is placed where V_t has fallen far, a second after the field went."""
    k = s.k_event
    ref = slice(0, max(k // 2, 10))
    out = k
    for c in ("v_t", "i_fd"):
        x = s[c]
        level, noise = float(np.median(x[ref])), float(np.std(np.diff(x[ref]))) / math.sqrt(2)
        band = max(6.0 * noise, 0.005 * abs(level))
        off = np.flatnonzero(np.abs(x[: k + 1] - level) > band)
        # the last run of samples off the level that reaches the event
        if off.size and off[-1] == k:
            gaps = np.flatnonzero(np.diff(off) > 1)
            out = min(out, int(off[gaps[-1] + 1] if gaps.size else off[0]))
    return out


def one_event(s: ScenarioData) -> FieldEvent:
    """T'_d0 / c for one event: the field circuit's integral from the plateau before against the
    V_t it has moved by, over the event's transient."""
    lead = int(round(LEAD_SECONDS / s.dt))
    k0 = departure(s)
    pre, post = slice(0, max(k0 - lead, 10)), s.steady_slice()
    v0, u0, i0 = _plateau(s, pre)
    v1, u1, i1 = _plateau(s, post)
    # the field winding's resistance at this test's temperature, both plateaus' (after a
    # de-excitation, where U_f = I_f = 0, the one before)
    k_e = (u0 * i0 + u1 * i1) / (u0 * u0 + u1 * u1)
    a = pre.stop
    g = k_e * s["v_f"][a:] - s["i_fd"][a:]
    integral = cumulative_trapezoid(g, dx=s.dt, initial=0.0)
    moved = s["v_t"][a:] - v0
    # T'_d0 (V_t(t) - V_t0) = the integral to t at every t once the dampers have settled: fitted
    # over the transient from a third of the way to where V_t settles (and a second on), not
    # integrated along the whole plateau, where a recorder's slow drift would add up
    delta = v1 - v0
    share = moved / delta
    settled = np.flatnonzero(share >= SETTLED)
    end = min((int(settled[0]) if settled.size else len(g) - 1) + int(round(TAIL_SECONDS / s.dt)), len(g))
    use = np.flatnonzero(share[:end] >= FROM_SHARE)
    x, y = moved[use], integral[use]
    slope = float(x @ y / (x @ x)) if use.size else float(integral[end - 1] / delta)
    moved_i = s["i_fd"][a:] - i0
    per_volt = float(x @ moved_i[use] / (x @ x)) if use.size else float((i1 - i0) / delta)
    misfit = float(np.max(np.abs(y - slope * x)) / abs(slope * delta)) if use.size and slope else math.nan
    return FieldEvent(s.name, (v0, i0), (v1, i1), delta, k_e, slope, per_volt, misfit)


def by_file(values: Sequence[tuple[str, float]]) -> tuple[float, float, int]:
    """(mean, its std, files) of per-event figures (scenario name, value): the events of one test
    file share its temperature and its recorder's offsets, so each file is one figure and the std
    is their spread; with one file, its events' own agreement is all there is (NaN with one event)."""
    files: dict[str, list[float]] = {}
    for name, v in values:
        files.setdefault(file_of(name), []).append(v)
    per_file = np.array([np.mean(v) for v in files.values()])
    if len(per_file) > 1:
        return float(np.mean(per_file)), float(np.std(per_file, ddof=1) / math.sqrt(len(per_file))), len(files)
    each = np.array([v for _, v in values])
    spread = float(np.std(each, ddof=1) / math.sqrt(len(each))) if len(each) > 1 else math.nan
    return float(np.mean(each)), spread, 1


BUILD_UP_POINTS = 5  # samples of a build-up on the linear part, at least, to draw the air-gap line
TOP_SHARE = 0.97  # of the plateau's V_t after a build-up: where its rise has reached the top
DECAY_SECONDS = 10.0  # after the top: where the rotor's other circuits' current is seen to die away
# the time constants tried for those circuits (dampers, the poles' iron, lumped as one), s
ROTOR_CIRCUIT_T = tuple(float(x) for x in np.geomspace(0.05, 5.0, 41))
ROTOR_CIRCUIT_RMS = 1.1  # fits within this of the best one's RMS: the air-gap line's spread among them


@dataclass(frozen=True)
class BuildUpLine:
    """The air-gap line a build-up from standstill traversed: ``c``, V_t per recorded I_f, and its
    relative std; and the rotor's other circuits the rise drove (``tau`` s of field current per pu
    of V_t per s above the open-circuit curve, dying away in ``t_k`` s)."""

    c: float
    rel_std: float
    tau: float
    t_k: float
    scenario: str

    def note(self) -> str:
        return (
            f"{self.scenario}: the field current rose above the open-circuit curve by {self.tau:.2g} s x dV_t/dt "
            f"(the rotor's other circuits, dying away in {self.t_k:.2g} s at the top), taken out of the air-gap line"
        )


def _lagged(x: np.ndarray, dt: float, t_k: float) -> np.ndarray:
    """``x`` through a first-order lag of ``t_k`` from rest (exact for samples held over ``dt``)."""
    from scipy.signal import lfilter

    a = math.exp(-dt / t_k)
    return np.asarray(lfilter([1.0 - a], [1.0, -a], x), dtype=float)


def build_up_line(s: ScenarioData) -> BuildUpLine | None:
    """The air-gap line from a build-up from standstill: the event's plateau before it below
    PLATEAU_FLOOR (the remanence), the one after above the linear part; None for any other event.
    A black start's build-up traverses the whole open-circuit curve: its linear part is the
    air-gap line that plateaus above the knee cannot give.

    But on the way up the field current is not the open-circuit curve's: a rising flux drives
    currents in the rotor's other circuits (dampers, the poles' iron) that the field's makes up,
    so I_f runs above the curve by tau dV_t/dt and, at the top, dies away onto it (Zakucac's
    unit A: 855 A at 16 kV on the rise, 795 A three seconds later; taken as it is, the rise's line
    put the plateau at 16 kV below the air-gap line, and T'_d0 6 % short). Fitted together: on the
    rise's linear part I_f = g V_t + I_0 + K L(dV_t/dt), over the DECAY_SECONDS after the top
    I_f = a + b (V_t - V_top) + K L(dV_t/dt), L a first-order lag of T_k (tried over
    ROTOR_CIRCUIT_T): linear in (g, I_0, a, b, K) for each T_k; the best T_k's g is the line
    (c = 1/g), its std the fit's and the spread of g among the T_k that fit nearly as well."""
    v, i = s["v_t"], s["i_fd"]
    before = v[: max(departure(s) - int(round(LEAD_SECONDS / s.dt)), 10)]  # as one_event takes its plateau
    v_end = float(np.mean(v[s.steady_slice()]))
    if float(np.mean(before)) >= PLATEAU_FLOOR or v_end < LINEAR_PART[1]:
        return None
    reached = np.flatnonzero(v >= TOP_SHARE * v_end)
    if not reached.size:
        return None
    top = int(reached[0])
    k = np.arange(len(v))
    part = np.flatnonzero((v >= LINEAR_PART[0]) & (v <= LINEAR_PART[1]) & (k < top))
    decay = np.flatnonzero((k >= top) & (k <= top + int(round(DECAY_SECONDS / s.dt))))
    if part.size < BUILD_UP_POINTS or decay.size < BUILD_UP_POINTS or np.ptp(i[part]) <= 0:
        return None
    rate = np.gradient(v, s.dt)
    rows = np.r_[part, decay]
    design = np.zeros((rows.size, 5))
    design[: part.size, 0], design[: part.size, 1] = v[part], 1.0
    design[part.size :, 2], design[part.size :, 3] = 1.0, v[decay] - v[top]
    fits = []
    for t_k in ROTOR_CIRCUIT_T:
        design[:, 4] = _lagged(rate, s.dt, t_k)[rows]
        coef, *_ = np.linalg.lstsq(design, i[rows], rcond=None)
        r = i[rows] - design @ coef
        fits.append((float(np.sqrt(np.mean(r * r))), t_k, coef, r))
    best = min(fits, key=lambda f: f[0])
    rms, t_k, coef, r = best
    g = float(coef[0])
    if not g > 0:
        return None
    design[:, 4] = _lagged(rate, s.dt, t_k)[rows]
    dof = max(rows.size - design.shape[1], 1)
    cov = float(r @ r) / dof * np.linalg.pinv(design.T @ design)
    near = [float(f[2][0]) for f in fits if f[0] <= ROTOR_CIRCUIT_RMS * rms]
    rel = math.hypot(math.sqrt(max(float(cov[0, 0]), 0.0)) / g, (max(near) - min(near)) / (2.0 * g))
    return BuildUpLine(1.0 / g, rel, float(coef[4]) / g, t_k, s.name)


def build_up_lines(scs: Sequence[ScenarioData]) -> dict[str, BuildUpLine]:
    """The air-gap line of each build-up from standstill among the field events, by scenario."""
    return {s.name: line for s in scs if (line := build_up_line(s)) is not None}


def field_circuit(scenarios: Sequence[ScenarioData], saturation: tuple[float, float] | None) -> FieldCircuitResult:
    scs = field_events(scenarios)
    if not scs:
        raise FieldCircuitError("no no-load event with V_t, E_fd and I_fd recorded and V_t moving between two plateaus")
    events = [one_event(s) for s in scs]
    plateaus = [(v, i, e.scenario) for e in events for v, i in (e.before, e.after) if v >= PLATEAU_FLOOR]
    lines = build_up_lines(scs)
    traversed = [(line.c, name) for name, line in lines.items()]
    base = field_current_base([p[0] for p in plateaus], [p[1] for p in plateaus], saturation, traversed)
    mean, spread, n_files = by_file([(e.scenario, e.time_per_base) for e in events])
    tau = base.scale * mean
    sd = base.scale * spread
    if base.determined and math.isfinite(base.scatter):
        sd = math.hypot(sd, tau * base.scatter)  # the curve's misfit to the plateaus is c's own error
    if not math.isfinite(sd) and saturation is None and lines:
        # one build-up: its air-gap line's own std is c's, the integral's is its (a whole traverse
        # from standstill against a step's few per cent, and its plateau's resistance)
        # and the integral's largest misfit to T'_d0 x V_t along the rise, which sampling and the
        # dampers leave (a 96 ms recorder's edges of the field forcing)
        fits = [e.fit_share for e in events if e.scenario in lines and math.isfinite(e.fit_share)]
        sd = tau * math.hypot(
            float(np.sqrt(np.mean([line.rel_std**2 for line in lines.values()]))), max(fits) if fits else math.nan
        )
    values = ", ".join(f"{base.scale * e.time_per_base:.3g} s" for e in events)
    est = Estimate(tau, sd, drivers=[e.scenario for e in events][:3])
    if saturation is None:
        for line in lines.values():
            est.add_note(line.note())
    est.add_note(
        f"T'_d0 from the field circuit at no load (the integral of E_fd - X_ad I_fd over each event per V_t it "
        f"moved; {len(events)} event(s) in {n_files} file(s): {values}); the field current's base: {base.source}"
    )
    if not base.determined:
        est.bound = "at least"
        est.disqualify(
            f"T'_d0 is at least {tau:.3g} s (on the air-gap line through the least saturated plateau; S >= 0) and "
            "grows with the saturation at the plateaus: give the machine's open-circuit curve (--saturation "
            "S10,S12, its datasheet's S(1.0), S(1.2)) or record a no-load plateau below the knee"
        )
    elif not math.isfinite(sd) or sd <= 0:
        est.disqualify("T'_d0 from one event in one file: no spread to judge it by")
    if saturation is not None and base.scatter > SATURATION_GAP:
        est.disqualify(
            f"the open-circuit curve (S(1.0) = {saturation[0]:g}, S(1.2) = {saturation[1]:g}) misses the "
            f"no-load plateaus by up to {100 * base.scatter:.1f} %: is it this machine's?"
        )
    leak = field_leakage(events, base) if base.determined else None
    if leak is not None and leak.shows:
        each = ", ".join(f"{t:.3g} s at {r:.2f}" for _, r, t in leak.per_volt)
        est.add_note(
            f"the field's own leakage flux, which does not saturate, shows: the test files' T'_d0 rise with the field "
            f"current moved per V_t ({each}; 1 on the air-gap line), by T_fl {leak.leakage:.3g} s per unit, so the "
            f"unsaturated T'_d0 (IEEE 115's, a datasheet's) is about {leak.unsaturated:.3g} s; GENSAL's and "
            "GENROU's form take the leakage flux as saturating and one T'_d0: the one given is the events' mean, "
            "which a record plays"
        )
    return FieldCircuitResult(est, base, events, plateaus, leak, list(lines.values()) if saturation is None else [])


@dataclass
class MachineField:
    """The recorded E_fd on the machine's base, test file by test file: E_fd = ``scale[file]``
    x the recorded U_f, where the scale is c (the field current's base, from the no-load
    plateaus) times that file's own I_f per U_f (its field winding's resistance at its temperature)."""

    scale: dict[str, float]
    base: FieldCurrentBase
    note: str

    def on_base(self) -> bool:
        """Whether the recorded E_fd is already on the machine's base (every file within 5 %)."""
        return all(abs(k - 1.0) <= ON_BASE for k in self.scale.values())

    def time_constant_ratio(self, file: str, reference: Collection[str]) -> float:
        """A field time constant's value in ``file`` over its value in the ``reference`` files (T'_d0
        is L_ffd / R_fd, and a file's R_fd goes as 1 / its I_f per U_f): on the day's E_fd, put on
        the machine's base file by file, each file's T'_d0 is its own field winding's."""
        k_ref = sum(self.scale[f] for f in reference) / len(reference)
        return self.scale[file] / k_ref

    def applied(self, scenarios: Sequence[ScenarioData], note: str) -> list[ScenarioData]:
        """The scenarios with E_fd on the machine's base, ``note`` added to each changed."""
        return [
            with_channels(s, {"v_f": self.scale[file_of(s)] * np.asarray(s["v_f"], float)}, note)
            if s.has("v_f") and file_of(s) in self.scale
            else s
            for s in scenarios
        ]


def _steady_parts(s: ScenarioData) -> list[slice]:
    """The scenario's plateau before its event (up to where V_t or I_f leaves it) and after it."""
    k0 = departure(s) - int(round(LEAD_SECONDS / s.dt))
    return [p for p in (slice(0, k0), s.steady_slice()) if p.stop - p.start >= 10]


def current_per_field_voltage(scenarios: Sequence[ScenarioData]) -> dict[str, float]:
    """Each test file's recorded I_f per U_f at its plateaus (before and after each event, on line
    or at no load; a de-excited one left out), by least squares through the origin: the inverse
    of its field winding's resistance at that test's temperature, in the recorder's units."""
    means: dict[str, list[tuple[float, float]]] = {}
    for s in scenarios:
        if not s.has("v_f", "i_fd"):
            continue
        for part in _steady_parts(s):
            _, u, i = _plateau(s, part)
            if abs(u) > FIELD_FLOOR:
                means.setdefault(file_of(s), []).append((u, i))
    return {f: float(sum(u * i for u, i in pts) / sum(u * u for u, _ in pts)) for f, pts in means.items()}


@dataclass(frozen=True)
class FieldResistance:
    """The field winding's resistance from the plateaus, test file by test file (U_f per I_f as
    recorded, times ``ohms_per_unit`` where the recording's field bases are in V and A: then in
    ohms). The files' spread is the winding's temperature, not noise: a test after hours on line
    reads more than one after a standstill."""

    per_file: dict[str, float]
    ohms_per_unit: float | None = None  # the bases' V per A; None: in the recorder's per unit

    @property
    def values(self) -> dict[str, float]:
        k = 1.0 if self.ohms_per_unit is None else self.ohms_per_unit
        return {f: k * r for f, r in self.per_file.items()}

    def as_dict(self) -> dict[str, Any]:
        v = np.array(list(self.values.values()))
        return {
            "unit": "ohm" if self.ohms_per_unit is not None else "U_f per I_f as recorded",
            "value": float(np.mean(v)),
            "std": float(np.std(v, ddof=1) / math.sqrt(len(v))) if len(v) > 1 else math.nan,
            "range": [float(v.min()), float(v.max())],
            "files": self.values,
        }


def field_resistance(scenarios: Sequence[ScenarioData], ohms_per_unit: float | None = None) -> FieldResistance | None:
    """The field winding's resistance at each test file's plateaus, or None where no file has a
    plateau with both U_f and I_f recorded."""
    per_volt = current_per_field_voltage(scenarios)
    per_file = {f: 1.0 / k for f, k in per_volt.items() if k > 0}
    return FieldResistance(per_file, ohms_per_unit) if per_file else None


def machine_field(scenarios: Sequence[ScenarioData], saturation: tuple[float, float] | None) -> MachineField | None:
    """E_fd's base per test file from the recorded field current, or None where a scenario with
    E_fd lacks I_fd or no no-load plateau is there. ``saturation``: the machine's S(1.0), S(1.2)
    (a record's, or held from the datasheet); without it the air-gap line, or the bound S >= 0
    gives where every plateau is saturated (said in the note)."""
    with_field = [s for s in scenarios if s.has("v_f")]
    if not with_field or not all(s.has("i_fd") for s in with_field):
        return None
    plateaus = [_plateau(s, part) for s in with_field if at_no_load(s) for part in _steady_parts(s)]
    plateaus = [p for p in plateaus if p[0] >= PLATEAU_FLOOR]
    if not plateaus:
        return None
    traversed = [(line.c, line.scenario) for line in build_up_lines(field_events(scenarios)).values()]
    base = field_current_base([p[0] for p in plateaus], [p[2] for p in plateaus], saturation, traversed)
    resistance = current_per_field_voltage(with_field)
    scale = {f: base.scale * k for f, k in resistance.items()}
    ks = np.array(list(resistance.values()))
    note = (
        f"E_fd put on the machine's base from the field current: X_ad I_fd = {base.scale:.4g} x I_f as recorded "
        f"({base.source}), and each test file's own I_f per U_f at its plateaus ({ks.min():.4g}-{ks.max():.4g}: "
        f"the field winding's resistance at that test's temperature): E_fd = {min(scale.values()):.4g}-"
        f"{max(scale.values()):.4g} x U_f as recorded"
    )
    if not base.determined:
        note += " (on the air-gap line through the least saturated plateau: the curve is not known here)"
    return MachineField(scale, base, note)


# on line, the fit spans this long before and after the event (s): its transient, then the plateau;
# and the other windows whose answers the std carries (what the cut moves)
WINDOW = (2.0, 6.0)
OTHER_WINDOWS = ((1.0, 4.0), (4.0, 10.0))


@dataclass
class OnLineResult:
    X_d: Estimate
    X_d_prime: Estimate
    events: list[dict[str, float | str]]


def _on_line_event(
    s: ScenarioData,
    field: MachineField,
    t_d0: float,
    x_q: float,
    saturation: tuple[float, float] | None,
    window: tuple[float, float] = WINDOW,
) -> tuple[float, float]:
    """(X'_d, X_d) from one on-line event: E'_q's course from the field circuit, E'_q = V_q + X'_d I_d
    for X'_d, then X_ad I_fd = E'_q (1 + S(E'_q)) + (X_d - X'_d) I_d (GENSAL's form) for X_d."""
    r = with_rotor_angle(s, x_q, "held")
    v_q, i_d = r["v_q"], r["i_d"]
    x_ad_i_fd = field.base.scale * s["i_fd"]
    g = field.scale[file_of(s)] * s["v_f"] - x_ad_i_fd
    course = cumulative_trapezoid(g, dx=s.dt, initial=0.0) / t_d0
    # a short window about the event: a long one carries the recorder's drift into E'_q's course
    a = max(s.k_event - int(round(window[0] / s.dt)), 0)
    b = min(s.k_event + int(round(window[1] / s.dt)), s.n)
    sl = slice(a, b)
    # V_q - course = E'_q(start) - X'_d I_d
    design = np.column_stack([np.ones(b - a), -i_d[sl]])
    (e0, x_dp), *_ = np.linalg.lstsq(design, v_q[sl] - course[sl], rcond=None)
    e_q = e0 + course[sl]
    s10, s12 = saturation if saturation is not None else (0.0, 0.0)
    held_up = x_ad_i_fd[sl] - no_load_field(e_q, s10, s12)
    x_d = float(x_dp) + float(held_up @ i_d[sl] / (i_d[sl] @ i_d[sl]))
    return float(x_dp), x_d


def on_line(
    scenarios: Sequence[ScenarioData],
    field: MachineField,
    t_d0: Estimate,
    x_q: float,
    saturation: tuple[float, float] | None,
    t_d0_files: Collection[str] = (),
) -> OnLineResult:
    """X'_d and X_d from on-line events where the field current is recorded, the rotor angle
    reconstructed with ``x_q`` (held) and T'_d0 known (the no-load field circuit's, or held).

    ``t_d0_files``: the test files T'_d0 was found in. T'_d0 is L_ffd / R_fd, and the field winding
    warms through a day (Mostar's on-line files' I_f per U_f is 2.5-4 % below the no-load files'),
    so each on-line file's T'_d0 is T'_d0 referred to its own field resistance; a held T'_d0 (no
    files) is taken as it is in every file.

    T'_d0 dE'_q/dt = E_fd - X_ad I_fd holds on line as at no load, so the field channels give
    E'_q's course through an event; the stator gives E'_q = V_q + X'_d I_d once the dampers have
    settled: X'_d, each event's E'_q at its start free. The field current then gives X_d through
    X_ad I_fd = E'_q (1 + S(E'_q)) + (X_d - X'_d) I_d. What the on-line tests fix is T'_d0 X'_d
    (the course's size per I_d), so T'_d0's std is carried into both."""
    scs = [s for s in scenarios if s.role == "identify" and s.has("v_t", "p_e", "q_e", "v_f", "i_fd")]
    scs = [s for s in scs if not at_no_load(s) and file_of(s) in field.scale]
    if not scs:
        raise FieldCircuitError("no on-line event with V_t, P, Q, E_fd and I_fd recorded")
    if not (math.isfinite(t_d0.value) and t_d0.value > 0):
        raise FieldCircuitError("T'_d0 is not known: the on-line field circuit needs it")

    reference = [f for f in t_d0_files if f in field.scale]
    ratio = {file_of(s): field.time_constant_ratio(file_of(s), reference) if reference else 1.0 for s in scs}

    def fit(tau: float, window: tuple[float, float] = WINDOW) -> list[tuple[str, float, float]]:
        return [(s.name, *_on_line_event(s, field, tau * ratio[file_of(s)], x_q, saturation, window)) for s in scs]

    each = fit(t_d0.value)
    x_dp, sd_dp, n_files = by_file([(n, a) for n, a, _ in each])
    x_d, sd_d, _ = by_file([(n, b) for n, _, b in each])
    # what the window's choice and T'_d0's std move the answers by (the largest of each), in
    # quadrature with the files' spread
    groups = [[fit(t_d0.value, w) for w in OTHER_WINDOWS]]
    if math.isfinite(t_d0.std) and t_d0.std > 0:
        groups.append([fit(t_d0.value + k * t_d0.std) for k in (-1.0, 1.0)])
    for group in groups:
        sd_dp = math.hypot(sd_dp, max(abs(by_file([(n, a) for n, a, _ in alt])[0] - x_dp) for alt in group))
        sd_d = math.hypot(sd_d, max(abs(by_file([(n, b) for n, _, b in alt])[0] - x_d) for alt in group))
    drivers = [n for n, _, _ in each][:3]
    where = (
        f"{len(each)} on-line event(s) in {n_files} file(s) ("
        + ", ".join(f"{n}: X'_d {a:.3g}, X_d {b:.3g}" for n, a, b in each)
        + f"), T'_d0 = {t_d0.value:.4g} s, X_q = {x_q:g} pu (held)"
    )
    if reference:
        where += (
            "; T'_d0 referred to each file's field resistance (its I_f per U_f against the no-load files'): x "
            + ", ".join(f"{r:.3f} in {f}" for f, r in ratio.items())
        )
    est_dp = Estimate(x_dp, sd_dp, drivers=drivers)
    est_dp.add_note(
        f"X'_d from the field circuit on line: E'_q's course from E_fd - X_ad I_fd, = V_q + X'_d I_d; {where}"
    )
    curve = "S(1.0) = {:g}, S(1.2) = {:g}".format(*saturation) if saturation else "the air-gap line"
    est_d = Estimate(x_d, sd_d, drivers=drivers)
    est_d.add_note(
        f"X_d from the field current on line: X_ad I_fd = E'_q (1 + S(E'_q)) + (X_d - X'_d) I_d on {curve}; {where}"
    )
    for e in (est_dp, est_d):
        if not t_d0.identifiable:
            e.disqualify("T'_d0, which it rests on, is not identified")
        elif not field.base.determined:
            e.disqualify("the field current's base is not determined (the open-circuit curve is not known)")
        elif not (math.isfinite(e.std) and e.std > 0):
            e.disqualify("one event in one file: no spread to judge it by")
    return OnLineResult(est_d, est_dp, [{"scenario": n, "X_d_prime": a, "X_d": b} for n, a, b in each])
