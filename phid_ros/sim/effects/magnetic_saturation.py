"""Open-circuit saturation as the planning models define it, through S(1.0) and S(1.2)."""

from __future__ import annotations

from functools import cached_property
from typing import Any

import numpy as np

from phid_ros.errors import SimulationError
from phid_ros.jit import maybe_jit
from phid_ros.sim.effects.base import Array, Compiled, EffectParameter, PlantEffect, RotorContext, Value, register

GENSAL, GENROU = 1, 2  # where it acts (its compiled terms' ``at``): on E'_q, or on |psi''| in both axes
FORMS = {"gensal": GENSAL, "genrou": GENROU}
SAT_CURVE, SAT_C1, SAT_C2, SAT_Q = range(4)  # its rows of the compiled play-in's coefficients


def saturation_curve(curve: str, s10: Any, s12: Any) -> tuple[Any, Any]:
    """The two constants of S(psi) through S(1.0) = s10 and S(1.2) = s12 (PSS/E's definitions).

    quadratic (GENROU, GENSAL): S = B (psi - A)^2 / psi above A, 0 below;
    exponential (GENROE, GENSAE): S = s10 psi^X with X = ln(s12 / s10) / ln 1.2.
    """
    s10, s12 = np.asarray(s10, float), np.asarray(s12, float)
    if curve == "exponential":
        return s10, np.log(s12 / s10) / np.log(1.2)
    r = np.sqrt(1.2 * s12 / s10)
    a = (1.2 - r) / (1.0 - r)
    return a, s10 / (1.0 - a) ** 2


def saturation_factor(exponential: bool, c1: Value, c2: Value, psi: Value) -> Value:
    """S(psi) for the constants of :func:`saturation_curve` (``exponential``: that curve, else
    the quadratic one)."""
    if exponential:
        return c1 * psi**c2
    over = np.maximum(psi - c1, 0.0)
    return c2 * over * over / psi


def no_load_field(v_t: Any, s10: float, s12: float) -> Any:
    """E_fd (X_ad I_fd) that holds the open-circuit machine at ``v_t``: V_t (1 + S(V_t)) on the
    quadratic curve through S(1.0), S(1.2) (at no load both forms saturate on V_t: E'_q, the
    air-gap flux); V_t on the air-gap line where the two do not make a curve (S(1.2) > S(1.0) > 0)."""
    v = np.asarray(v_t, float)
    if not s12 > s10 > 0:
        return v
    a, b = saturation_curve("quadratic", s10, s12)
    return v * (1.0 + saturation_factor(False, a, b, v))


def flux_magnitude(psi_d: Value, psi_q: Value) -> Value:
    """|psi''|, on which GENROU saturates."""
    return np.sqrt(psi_d * psi_d + psi_q * psi_q)


def q_share(params: Any, x_l: Value) -> Value:
    """GENROU's share of the saturation on the q axis, ``(X_q - X_l)/(X_d - X_l)``."""
    return (params.X_q - x_l) / (params.X_d - x_l)


_factor, _magnitude = maybe_jit(saturation_factor, inline=True), maybe_jit(flux_magnitude, inline=True)


def compiled_losses(
    x: Array, out: Array, coef: Array, c: int, r: int, at: int, psi_d: float, psi_q: float, i_d: float, i_q: float
) -> tuple[float, float]:
    """:meth:`MagneticSaturation.transient_losses` for one column of the compiled play-in."""
    e_q = x[2]
    s = _factor(
        coef[r + SAT_CURVE, c] > 0.5,
        coef[r + SAT_C1, c],
        coef[r + SAT_C2, c],
        e_q if at == GENSAL else _magnitude(psi_d, psi_q),
    )
    if at == GENSAL:
        return s * e_q, 0.0
    return s * psi_d, s * psi_q * coef[r + SAT_Q, c]


@register
class MagneticSaturation(PlantEffect):
    """Open-circuit saturation as the planning models define it, through S(1.0) and S(1.2).

    ``form=genrou`` (round rotor): on the air-gap flux magnitude |psi''| (the EMF behind the
    stator reactances), both axes: T'_d0 dE'_q/dt gains -S psi''_d and T'_q0 dE'_d/dt gains
    -S psi''_q (X_q - X_l)/(X_d - X_l). ``form=gensal`` (salient pole): on E'_q, d axis only,
    T'_d0 dE'_q/dt gains -S(E'_q) E'_q. ``curve``: quadratic (GENROU/GENSAL) or exponential
    (GENROE/GENSAE), see :func:`saturation_curve`.

    Before this form, phid's saturation was S(1.0) exp(b (E'_q - 1)) E'_q on the d axis: the
    GENSAL form with a curve no planning model uses. On a GENROU machine (ANDES) it explained
    only part of the gap and left X_q 20 % off, because GENROU saturates the q axis too.
    """

    name = "magnetic_saturation"
    compiled = Compiled(rows=("sat_curve", "sat_c1", "sat_c2", "sat_q"), losses=compiled_losses)
    parameters = (
        EffectParameter("s10", 0.08, "pu", "saturation factor at 1.0 pu", 0.02, 0.2, absent=0.0),
        EffectParameter("s12", 0.35, "pu", "saturation factor at 1.2 pu", 0.1, 0.8, absent=0.0),
        EffectParameter("form", "genrou", "", "where it acts (planning model)", choices=("genrou", "gensal")),
        EffectParameter(
            "curve", "quadratic", "", "S(psi) through S(1.0), S(1.2)", choices=("quadratic", "exponential")
        ),
    )

    def __init__(self, **values: Any) -> None:
        super().__init__(**values)
        if not self["s12"] > self["s10"]:
            raise SimulationError("effect magnetic_saturation: s12 must exceed s10")

    @cached_property
    def _constants(self) -> tuple[Any, Any]:
        return saturation_curve(self["curve"], self["s10"], self["s12"])

    def factor(self, psi: Any) -> Any:
        return saturation_factor(self["curve"] == "exponential", *self._constants, psi)

    def transient_losses(self, states: Array, ctx: RotorContext, params: Any) -> tuple[Any, Any]:
        if self["form"] == "gensal":
            return self.factor(ctx.e_q) * ctx.e_q, 0.0
        s = self.factor(flux_magnitude(ctx.psi_d, ctx.psi_q))
        return s * ctx.psi_d, s * ctx.psi_q * q_share(params, ctx.x_l)

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        c1, c2 = self._constants
        return {
            "sat_curve": 1.0 if self["curve"] == "exponential" else 0.0,
            "sat_c1": c1,
            "sat_c2": c2,
            "sat_q": q_share(plant.params, plant.x_l),
        }

    def kernel_setting(self, plant: Any, slot: slice) -> int:
        return FORMS[self["form"]]
