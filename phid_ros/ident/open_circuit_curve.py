"""The open-circuit curve in the planning models' form, from a unit's no-load recordings.

Points: every no-load plateau (V_t, I_f as recorded) the scenarios hold, the steady state before
each event and the one after it (a polled log's small set-point steps, a build-up's top);
plateaus of one file within ``SAME_LEVEL`` of each other in V_t are one point. The air-gap line
is the field current's base, ``X_ad I_fd = c I_f`` (:func:`phid_ros.ident.field_circuit.field_current_base`:
the line a build-up from standstill traversed, or the plateaus below the knee), and at each
point ``S(V_t) = c I_f / V_t - 1``, IEEE 115's definition and the planning models'.

The planning form is PSS/E's quadratic ``S = B (V - A)^2 / V`` above A, fitted to the points by
least squares on the field current's relative error and given as S(1.0) and S(1.2). Each is
determined only where the points reach it (within ``REACH`` below it, or beyond): the form is
never extrapolated as measured, so a curve measured up to rated voltage gives S(1.2) withheld,
its fitted value said.

Why plateaus, not the build-up's rise: on the way up the field current runs above the curve by
what the rotor's other circuits take (:class:`~phid_ros.ident.field_circuit.BuildUpLine`), and
a ramped rise lies on the rising branch of the iron's hysteresis: Zakucac's unit A's rise, its
rotor circuits taken out, read 3-5 % more field current between 0.88 and 0.97 pu than its
polled plateaus, which its own polled steps, lowered and raised, do not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from phid_ros.ident.field_circuit import PLATEAU_FLOOR, FieldCurrentBase
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import ScenarioData, file_of
from phid_ros.sim.effects.magnetic_saturation import saturation_factor

SAME_LEVEL = 0.002  # pu of V_t: plateaus of one file closer than this are one point
REACH = 0.02  # pu: S(x) is determined where a point lies at x - REACH or above
MIN_POINTS = 3  # points above the air-gap line's linear part that a fitted curve needs
KNEE_FROM = 0.5  # pu: the form's A is sought from here (hydro and turbo units bend above 0.7)


@dataclass(frozen=True)
class CurvePoint:
    v_t: float  # pu
    i_f: float  # as recorded (the map's unit)
    saturation: float  # c I_f / V_t - 1
    scenario: str
    branch: str  # "rising" after a rise, "falling" after a fall, "" where the move before it is not seen


@dataclass
class OpenCircuitCurve:
    c: float  # V_t per recorded I_f on the air-gap line (X_ad I_fd = c I_f)
    air_gap: str  # where the line comes from
    points: list[CurvePoint]
    s10: Estimate
    s12: Estimate
    a: float  # the quadratic form's A (pu) and B; NaN where no curve is fitted
    b: float
    worst: float  # the fitted curve's largest relative error in I_f at the points
    notes: list[str] = field(default_factory=list)

    def field_at(self, v_t: Any) -> Any:
        """I_f (as recorded) the curve gives at ``v_t``."""
        return field_on_curve(self.c, self.a, self.b, v_t)

    def misses(self, v_t: Sequence[float], i_f: Sequence[float]) -> float:
        """The curve's largest relative error in I_f at other points (a sister unit's plateaus)."""
        v, i = np.asarray(v_t, float), np.asarray(i_f, float)
        return float(np.max(np.abs(self.field_at(v) / i - 1.0))) if v.size else math.nan

    def worst_by_branch(self) -> dict[str, float]:
        """The largest relative error in I_f at the points reached by a rise, and by a fall: the
        iron's hysteresis puts the falling branch's field current below the rising one's."""
        out = {}
        for branch in ("rising", "falling"):
            at = [p for p in self.points if p.branch == branch]
            if at:
                out[branch] = self.misses([p.v_t for p in at], [p.i_f for p in at])
        return out

    def as_dict(self) -> dict[str, Any]:
        return {
            "air_gap_line": self.c,
            "air_gap_line_source": self.air_gap,
            "S10": self.s10.as_dict(),
            "S12": self.s12.as_dict(),
            "quadratic": {"A": self.a, "B": self.b},
            "worst_relative_error": self.worst,
            "worst_relative_error_by_branch": self.worst_by_branch(),
            "points": [p.__dict__ for p in self.points],
            "notes": self.notes,
        }


def field_on_curve(c: float, a: float, b: float, v_t: Any) -> Any:
    """I_f (as recorded) at ``v_t`` on the air-gap line ``c`` bent by the quadratic form's (A, B):
    V_t (1 + S(V_t)) / c; the line itself where A is NaN (no curve fitted)."""
    v = np.asarray(v_t, float)
    sat = saturation_factor(False, a, b, v) if math.isfinite(a) else 0.0
    return v * (1.0 + sat) / c


def no_load_plateaus(scenarios: Sequence[ScenarioData]) -> list[tuple[float, float, str, str]]:
    """(V_t, I_f, scenario, branch) of each no-load scenario's plateau before its event and after
    it, above ``PLATEAU_FLOOR``; one file's plateaus within ``SAME_LEVEL`` merged (the windows of
    consecutive steps share them), in the order met."""
    found: list[tuple[float, float, str, str]] = []
    for s in scenarios:
        if not s.has("v_t", "i_fd"):
            continue
        v0, i0 = (float(np.mean(s[c][s.pre_slice()])) for c in ("v_t", "i_fd"))
        v1, i1 = (float(np.mean(s[c][s.steady_slice()])) for c in ("v_t", "i_fd"))
        branch = "rising" if v1 > v0 else "falling"
        for v, i, how in ((v0, i0, ""), (v1, i1, branch)):
            if v < PLATEAU_FLOOR or not (math.isfinite(v) and math.isfinite(i) and i > 0):
                continue
            same = [k for k, p in enumerate(found) if file_of(p[2]) == file_of(s.name) and abs(p[0] - v) < SAME_LEVEL]
            if same:
                k = same[0]
                p = found[k]
                found[k] = (0.5 * (p[0] + v), 0.5 * (p[1] + i), p[2], p[3] or how)
            else:
                found.append((v, i, s.name, how))
    return found


def open_circuit_curve(
    base: FieldCurrentBase, scenarios: Sequence[ScenarioData], base_rel_std: float = math.nan
) -> OpenCircuitCurve | None:
    """The curve through the scenarios' no-load plateaus on ``base``'s air-gap line (see the
    module); None where the base is not determined or there are no plateaus. ``base_rel_std``:
    the air-gap line's relative std (a build-up's), which every S carries as (1 + S) times it."""
    plateaus = no_load_plateaus(scenarios)
    if not base.determined or not plateaus:
        return None
    c = base.scale
    points = [CurvePoint(v, i, c * i / v - 1.0, n, br) for v, i, n, br in plateaus]
    v = np.array([p.v_t for p in points])
    i_f = np.array([p.i_f for p in points])
    reach = float(v.max())
    notes = [f"{len(points)} no-load plateau(s) at V_t {v.min():.3f}-{reach:.3f} pu"]
    sat = np.array([p.saturation for p in points])
    bent = v[(v > KNEE_FROM) & (sat > 0.0)]
    if bent.size < MIN_POINTS:
        notes.append(f"{bent.size} plateau(s) above the air-gap line: no curve fitted (needs {MIN_POINTS})")
        a = b = math.nan
        s10, s12 = _not_fitted(1.0, reach), _not_fitted(1.2, reach)
        return OpenCircuitCurve(c, base.source, points, s10, s12, a, b, _worst(c, v, i_f, a, b), notes)
    a, b, cov = _fit(c, v, i_f)
    s10 = _at(1.0, a, b, cov, reach, base_rel_std)
    s12 = _at(1.2, a, b, cov, reach, base_rel_std)
    return OpenCircuitCurve(c, base.source, points, s10, s12, a, b, _worst(c, v, i_f, a, b), notes)


def _residual(c: float, v: np.ndarray, i_f: np.ndarray, a: float, b: float) -> np.ndarray:
    return v * (1.0 + saturation_factor(False, a, b, v)) / (c * i_f) - 1.0


def _worst(c: float, v: np.ndarray, i_f: np.ndarray, a: float, b: float) -> float:
    r = _residual(c, v, i_f, a, b) if math.isfinite(a) else v / (c * i_f) - 1.0
    return float(np.max(np.abs(r)))


def _fit(c: float, v: np.ndarray, i_f: np.ndarray) -> tuple[float, float, np.ndarray]:
    """The quadratic form's (A, B) by least squares, and their covariance (the residuals' own
    scatter: a handful of plateaus, each a recorder's mean)."""
    top = int(np.argmax(v))
    s_top = max(c * i_f[top] / v[top] - 1.0, 1e-4)
    a0 = 0.5 * (KNEE_FROM + v[top])
    b0 = s_top * v[top] / max(v[top] - a0, 1e-3) ** 2
    sol = least_squares(
        lambda x: _residual(c, v, i_f, x[0], x[1]),
        [a0, b0],
        bounds=([KNEE_FROM, 0.0], [float(v[top]) - 1e-3, 1e3]),
    )
    dof = max(v.size - 2, 1)
    s2 = float(sol.fun @ sol.fun) / dof
    jac = np.asarray(sol.jac, float)
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    return float(sol.x[0]), float(sol.x[1]), cov


def _at(x: float, a: float, b: float, cov: np.ndarray, reach: float, base_rel_std: float) -> Estimate:
    """S(x) on the fitted form, its std from the fit's and the air-gap line's; determined where
    the points reach x (within REACH)."""
    value = float(saturation_factor(False, a, b, x))
    over = max(x - a, 0.0)
    grad = np.array([-2.0 * b * over / x, over * over / x])
    fit_sd = math.sqrt(max(float(grad @ cov @ grad), 0.0))
    line_sd = (1.0 + value) * base_rel_std if math.isfinite(base_rel_std) else 0.0
    est = Estimate(value, math.hypot(fit_sd, line_sd), note=f"the no-load plateaus' curve at {x:g} pu")
    if reach < x - REACH:
        est.disqualify(
            f"S({x:g}): the no-load plateaus reach {reach:.3f} pu; the quadratic form through them puts it at "
            f"{value:.3g}, not measured"
        )
    return est


def _not_fitted(x: float, reach: float) -> Estimate:
    est = Estimate(math.nan, math.nan)
    est.disqualify(f"S({x:g}): no curve through the no-load plateaus (they reach {reach:.3f} pu)")
    return est
