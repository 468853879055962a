"""The steady-state characteristics of IEEE 115 (Std 115-2019, clause 4): the air-gap line, the
unsaturated synchronous reactance X_du, the short-circuit ratio and the open-circuit saturation,
from the open- and short-circuit curves.

- The air-gap line is the open-circuit curve's straight part through the origin: fitted on
  the points between 0.2 and 0.8 pu of voltage, a point more than 3 % off the line is named and
  left out (a reading off by a remanence or a misread meter), the line refitted once; a point
  above the linear part more than 3 % below the line (saturation only raises the field current)
  is named and left out likewise. Its
  field current at rated voltage, I_fg, is the field's per-unit base on the air-gap line.
- The short-circuit curve is linear (no saturation at short circuit): I_fsi, the field current
  for rated armature current, is its slope through the origin.
- X_du = I_fsi / I_fg; the short-circuit ratio SCR = I_f(OCC at rated voltage) / I_fsi, and
  1/SCR, the synchronous reactance at rated voltage (saturated).
- The saturation S(V) = I_f / (I_fg V) - 1 at each measured point; S(1.0) and S(1.2) read on the
  measured curve (monotone piecewise-cubic between the points, never extrapolated), as the
  planning models define them; the planning models' quadratic curve through those two is
  compared with every measured point from 0.8 to 1.3 pu (its largest relative error reported).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import PchipInterpolator

from phid_ros.errors import StageError
from phid_ros.ident.results import Estimate

Array = NDArray[np.float64]
LINEAR_PART = (0.2, 0.8)  # pu of voltage: where the air-gap line is fitted
OFF_THE_LINE = 0.03  # a linear-part point further than this from the line is left out
PLANNING_RANGE = (0.8, 1.3)  # pu: where the quadratic curve is compared with the measured points


class CharacteristicsError(StageError):
    """Curves that cannot give the characteristics (too few points, no linear part)."""


@dataclass
class Characteristics:
    i_fg: Estimate  # A: field current for rated voltage on the air-gap line
    i_fsi: Estimate  # A: field current for rated armature current at short circuit
    x_du: Estimate  # pu
    x_d_rated: Estimate  # pu: 1/SCR
    s10: Estimate
    s12: Estimate
    occ_points: list[tuple[float, float, float]]  # (V pu, I_f measured A, S at the point)
    planning_worst: float  # the quadratic curve's largest relative error, PLANNING_RANGE
    left_out: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def scr(self) -> float:
        return 1.0 / self.x_d_rated.value

    def as_dict(self) -> dict[str, object]:
        est = {n: getattr(self, n).as_dict() for n in ("i_fg", "i_fsi", "x_du", "x_d_rated", "s10", "s12")}
        return {
            **est,
            "short_circuit_ratio": self.scr,
            "occ_points": [{"v_pu": v, "i_f_a": i, "saturation": s} for v, i, s in self.occ_points],
            "planning_curve_worst_relative_error": self.planning_worst,
            "left_out": self.left_out,
            "notes": self.notes,
        }


def air_gap_line(v: Array, i_f: Array) -> tuple[float, float, list[int]]:
    """(I_fg, its std, the indices of linear-part points left out)."""
    part = np.flatnonzero((v >= LINEAR_PART[0]) & (v <= LINEAR_PART[1]))
    if part.size < 2:
        raise CharacteristicsError(
            f"{part.size} open-circuit point(s) between {LINEAR_PART[0]} and {LINEAR_PART[1]} pu: the air-gap "
            "line needs at least 2"
        )
    slope = float(v[part] @ i_f[part] / (v[part] @ v[part]))
    off = part[np.abs(i_f[part] / (slope * v[part]) - 1.0) > OFF_THE_LINE]
    kept = np.setdiff1d(part, off)
    if kept.size < 2:
        kept, off = part, np.array([], dtype=int)
    slope = float(v[kept] @ i_f[kept] / (v[kept] @ v[kept]))
    r = i_f[kept] - slope * v[kept]
    sd = math.sqrt(float(r @ r) / max(kept.size - 1, 1) / float(v[kept] @ v[kept]))
    return slope, sd, [int(k) for k in off]


def characterise(occ_i_f: Array, occ_v: Array, scc_i_f: Array, scc_i_a: Array) -> Characteristics:
    order = np.argsort(occ_v)
    v, i_f = np.asarray(occ_v, float)[order], np.asarray(occ_i_f, float)[order]
    if np.any(np.diff(v) <= 0):
        raise CharacteristicsError("two open-circuit points at the same voltage")
    if len(v) < 4 or len(scc_i_a) < 2:
        raise CharacteristicsError(f"{len(v)} OCC and {len(scc_i_a)} SCC points: needs at least 4 and 2")
    g, sd_g, off = air_gap_line(v, i_f)
    left_out = [
        f"OCC point {v[k]:.3f} pu, {i_f[k]:.4g} A: {100 * (i_f[k] / (g * v[k]) - 1):+.1f} % off the air-gap line"
        for k in off
    ]

    ia, fi = np.asarray(scc_i_a, float), np.asarray(scc_i_f, float)
    s = float(ia @ fi / (ia @ ia))
    resid = fi - s * ia
    sd_s = math.sqrt(float(resid @ resid) / max(len(ia) - 1, 1) / float(ia @ ia))

    below = _below_the_air_gap_line(v, i_f, g, off)
    left_out += [
        f"OCC point {v[k]:.3f} pu, {i_f[k]:.4g} A: {100 * (i_f[k] / (g * v[k]) - 1):+.1f} % below the air-gap line "
        "(saturation only raises the field current: a misread point)"
        for k in below
    ]
    keep = np.setdiff1d(np.arange(len(v)), [*off, *below])
    curve = PchipInterpolator(v[keep], i_f[keep], extrapolate=False)
    notes: list[str] = []

    def saturation_at(x: float) -> Estimate:
        value = float(curve(x))
        if not math.isfinite(value):
            notes.append(f"S({x:g}): the open-circuit curve was not measured up to {x:g} pu")
            return Estimate(math.nan, math.nan, identifiable=False, note=f"not measured up to {x:g} pu")
        sat = value / (g * x) - 1.0
        return Estimate(sat, (1.0 + sat) * sd_g / g, note=f"the measured OCC at {x:g} pu over the air-gap line's")

    s10, s12 = saturation_at(1.0), saturation_at(1.2)
    at_rated = float(curve(1.0))
    x_du = s / g
    x_rated = s / at_rated if math.isfinite(at_rated) else math.nan
    planning = _planning_worst(v[keep], i_f[keep], g, s10.value, s12.value)
    return Characteristics(
        i_fg=Estimate(g, sd_g, note="the OCC's air-gap line at rated voltage"),
        i_fsi=Estimate(s, sd_s, note="the SCC at rated armature current"),
        x_du=Estimate(x_du, x_du * math.hypot(sd_s / s, sd_g / g), note="IEEE 115: I_fsi / I_fg (unsaturated)"),
        x_d_rated=Estimate(
            x_rated, x_rated * sd_s / s, note="1/SCR: I_fsi / I_f on the OCC at rated voltage (saturated)"
        ),
        s10=s10,
        s12=s12,
        occ_points=[(float(a), float(b), float(b / (g * a) - 1.0)) for a, b in zip(v, i_f)],
        planning_worst=planning,
        left_out=left_out,
        notes=notes,
    )


def _below_the_air_gap_line(v: Array, i_f: Array, g: float, off: list[int]) -> list[int]:
    """The points above the linear part that lie further below the air-gap line than
    :data:`OFF_THE_LINE`: an iron core's saturation only ever raises the field current a voltage
    takes, so such a point is a misreading; read as measured it gave S(1.0) = -0.113 and moved
    the short-circuit ratio by 22 %, naming no point."""
    above = np.flatnonzero(v > LINEAR_PART[1])
    return [int(k) for k in above if k not in off and i_f[k] / (g * v[k]) - 1.0 < -OFF_THE_LINE]


def _planning_worst(v: Array, i_f: Array, g: float, s10: float, s12: float) -> float:
    """The largest relative error of I_fg V (1 + S(V)), S the planning models' quadratic through
    S(1.0), S(1.2) (:func:`phid_ros.sim.effects.magnetic_saturation.saturation_curve`), over the measured points in
    PLANNING_RANGE (NaN where the two are not both known and S(1.2) > S(1.0) > 0)."""
    from phid_ros.sim.effects.magnetic_saturation import saturation_curve, saturation_factor

    if not (math.isfinite(s10) and math.isfinite(s12) and s12 > s10 > 0):
        return math.nan
    a, b = saturation_curve("quadratic", s10, s12)
    part = (v >= PLANNING_RANGE[0]) & (v <= PLANNING_RANGE[1])
    model = g * v[part] * (1.0 + saturation_factor(False, a, b, v[part]))
    return float(np.max(np.abs(model / i_f[part] - 1.0))) if part.any() else math.nan
