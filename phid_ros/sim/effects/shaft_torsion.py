"""Turbine and generator as two masses on an elastic shaft: one torsional mode."""

from __future__ import annotations

from typing import Any

import numpy as np

from phid_ros.jit import maybe_jit
from phid_ros.model.conventions import omega_s
from phid_ros.model.equations import rotor_angle, swing
from phid_ros.sim import jitted
from phid_ros.sim.effects.base import Array, Compiled, EffectParameter, PlantEffect, RotorContext, Value, register

ROWS = ("inv_2h_t", "inv_2h_g", "k_shaft", "d_shaft")  # its rows of the compiled play-in's coefficients
INV_2H_T, INV_2H_G, K_SHAFT, D_SHAFT = range(len(ROWS))


def shaft_torque(k: Value, d_shaft: Value, delta_t: Value, delta: Value, omega_t: Value, omega: Value) -> Value:
    """The elastic shaft's torque from the turbine to the generator."""
    return k * (delta_t - delta) + d_shaft * (omega_t - omega)


_torque = maybe_jit(shaft_torque, inline=True)


def compiled_swing(
    x: Array, out: Array, coef: Array, c: int, r: int, at: int, p_m: float, p_airgap: float, damping: float, ws: float
) -> float:
    """:meth:`ShaftTorsion.swing` and the turbine's derivatives for one column of the compiled play-in."""
    delta, omega = x[0], x[1]
    torque = _torque(coef[r + K_SHAFT, c], coef[r + D_SHAFT, c], x[at], delta, x[at + 1], omega)
    out[at] = jitted.rotor_angle(x[at + 1], ws)
    out[at + 1] = jitted.swing(p_m, torque, x[at + 1], 0.0, coef[r + INV_2H_T, c])
    return jitted.swing(torque, p_airgap, omega, damping, coef[r + INV_2H_G, c])


@register
class ShaftTorsion(PlantEffect):
    """Turbine and generator as two masses on an elastic shaft (one torsional mode).

    H splits into H_t = f H (turbine) and H_g = (1 - f) H (generator); the stiffness K
    follows from the torsional frequency; P_m acts on the turbine; the encoder sees the
    generator rotor.
    """

    name = "shaft_torsion"
    parameters = (
        EffectParameter("turbine_fraction", 0.6, "", "share of the inertia in the turbine", 0.3, 0.85),
        EffectParameter("f_torsion_hz", 15.0, "Hz", "torsional mode frequency", 5.0, 40.0),
        EffectParameter("d_shaft", 0.5, "pu", "damping across the shaft", 0.0, 5.0),
    )
    state_names = ("delta_t", "omega_t")
    compiled = Compiled(ROWS, swing=compiled_swing)

    def _stiffness(self, params: Any, ws: float) -> tuple[Any, Any, Any]:
        h_t = self["turbine_fraction"] * params.H
        h_g = params.H - h_t
        k = (2 * np.pi * self["f_torsion_hz"]) ** 2 / (ws * (1 / (2 * h_t) + 1 / (2 * h_g)))
        return h_t, h_g, k

    def initial_states(self, ctx: RotorContext, plant: Any) -> list[float]:
        _, _, k = self._stiffness(plant.params, omega_s(plant.f_nominal_hz))
        return [ctx.delta + ctx.p_m / k, 1.0]

    def configure(self, plant: Any) -> None:
        self._constants = self._stiffness(plant.params, omega_s(plant.f_nominal_hz))

    def _torque(self, states: Array, ctx: RotorContext) -> Array:
        k = self._constants[2]  # the plant's: its parameters do not change while it runs
        return shaft_torque(k, self["d_shaft"], states[0], ctx.delta, states[1], ctx.omega)

    def swing(self, states: Array, ctx: RotorContext, params: Any) -> Array:
        # (6) for the generator's mass alone, driven by the shaft instead of P_m
        h_g = self._constants[1]
        return swing(self._torque(states, ctx), ctx.p_airgap, ctx.omega, ctx.damping, 1.0 / (2 * h_g))

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        h_t, h_g, k = self._constants
        return {"inv_2h_t": 1.0 / (2 * h_t), "inv_2h_g": 1.0 / (2 * h_g), "k_shaft": k, "d_shaft": self["d_shaft"]}

    def derivatives(self, states: Array, ctx: RotorContext, params: Any) -> list[Array]:
        # (5) and (6) for the turbine's mass: P_m in, the shaft's torque out, no damping of its own
        h_t = self._constants[0]
        omega_t = states[1]
        return [rotor_angle(omega_t, ctx.ws), swing(ctx.p_m, self._torque(states, ctx), omega_t, 0.0, 1.0 / (2 * h_t))]
