"""Damper windings as GENROU writes them: the subtransient EMF behind X''_d, X''_q."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from phid_ros.errors import SimulationError
from phid_ros.jit import maybe_jit
from phid_ros.sim.effects.base import (
    Array,
    Compiled,
    EffectParameter,
    PlantEffect,
    RotorContext,
    Value,
    leakage_default,
    register,
)

# its rows of the compiled play-in's coefficients
ROWS = ("x_dpp", "x_qpp", "t_d0pp", "t_q0pp", "xdp_l", "xqp_l", "g_d", "g_q", "load_d", "load_q")
X_DPP, X_QPP, T_D0PP, T_Q0PP, XDP_L, XQP_L, G_D, G_Q, LOAD_D, LOAD_Q = range(len(ROWS))


def damper_emf(g: Value, e: Value, psi_k: Value) -> Value:
    """One axis of GENROU's air-gap flux: ``psi'' = g E' + (1 - g) psi_k``."""
    return g * e + (1.0 - g) * psi_k


def damper_drives(
    e_q: Value, e_d: Value, psi_kd: Value, psi_kq: Value, i_d: Value, i_q: Value, xdp_l: Value, xqp_l: Value
) -> tuple[Value, Value]:
    """What drives the dampers: ``E'_q - psi_kd - (X'_d - X_l) I_d`` and ``E'_d - psi_kq + (X'_q - X_l) I_q``."""
    return e_q - psi_kd - xdp_l * i_d, e_d - psi_kq + xqp_l * i_q


_emf, _drives = maybe_jit(damper_emf, inline=True), maybe_jit(damper_drives, inline=True)


def compiled_emf(x: Array, coef: Array, c: int, r: int, at: int) -> tuple[float, float, float, float]:
    """:meth:`SubtransientDynamics.emf` for one column of the compiled play-in: the air-gap flux psi''."""
    psi_d = _emf(coef[r + G_D, c], x[2], x[at])
    psi_q = _emf(coef[r + G_Q, c], x[3], x[at + 1])
    return psi_d, psi_q, coef[r + X_DPP, c], coef[r + X_QPP, c]


def compiled_losses(
    x: Array, out: Array, coef: Array, c: int, r: int, at: int, psi_d: float, psi_q: float, i_d: float, i_q: float
) -> tuple[float, float]:
    """The dampers' load on the transient windings, and their own derivatives into ``out``."""
    drive_d, drive_q = _drives(x[2], x[3], x[at], x[at + 1], i_d, i_q, coef[r + XDP_L, c], coef[r + XQP_L, c])
    out[at] = drive_d / coef[r + T_D0PP, c]
    out[at + 1] = drive_q / coef[r + T_Q0PP, c]
    return coef[r + LOAD_D, c] * drive_d, coef[r + LOAD_Q, c] * drive_q


@register
class SubtransientDynamics(PlantEffect):
    """Damper windings as GENROU writes them (PSS/E; ANDES, OpenIPSL): psi_kd, psi_kq behind X''.

    T''_d0 dpsi_kd/dt = E'_q - psi_kd - (X'_d - X_l) I_d
    T''_q0 dpsi_kq/dt = E'_d - psi_kq + (X'_q - X_l) I_q
    psi''_d = g_d E'_q + (1 - g_d) psi_kd,   g_d = (X''_d - X_l)/(X'_d - X_l)   (same for q)
    V_q = psi''_d - X''_d I_d,   V_d = psi''_q + X''_q I_q
    and the damper currents load the transient windings: T'_d0 dE'_q/dt gains
    -(X_d - X'_d)(X'_d - X''_d)/(X'_d - X_l)^2 (E'_q - psi_kd - (X'_d - X_l) I_d), and likewise q.

    Before, phid used the simplified form T''_d0 dE''_q/dt = E'_q - E''_q - (X'_d - X''_d) I_d
    (no load on the field): on ANDES's GENROU the diagnosis then explained the damper transient
    with X'' and T'' 5-20 % off and left T'_q0 24 % off. With X''_q = X'_q the q damper is inert
    (GENSAL's single q winding is then X'_q, T'_q0). X_l is the leakage reactance; unset, it is
    :func:`leakage_default` of X''.
    """

    name = "subtransient_dynamics"
    parameters = (
        EffectParameter("x_dpp", 0.25, "pu", "d-axis subtransient reactance X''_d", 0.12, 0.4, absent="X_d_prime"),
        EffectParameter("x_qpp", 0.30, "pu", "q-axis subtransient reactance X''_q", 0.12, 0.5, absent="X_q_prime"),
        EffectParameter("t_d0pp", 0.03, "s", "d-axis subtransient time constant T''_d0", 0.01, 0.1),
        EffectParameter("t_q0pp", 0.05, "s", "q-axis subtransient time constant T''_q0", 0.01, 0.2),
        EffectParameter("x_l", math.nan, "pu", "stator leakage reactance X_l (unset: min(0.15, 0.8 X''))", 0.05, 0.3),
    )
    state_names = ("psi_kd", "psi_kq")
    provides_emf = True
    compiled = Compiled(ROWS, emf=compiled_emf, losses=compiled_losses)

    def as_dict(self) -> dict[str, Any]:
        # The X_l in force, not the "unset" NaN: a truth file names the machine that was simulated.
        doc = super().as_dict()
        if self.checked:
            doc["x_l"] = float(self.leakage(None))
        return doc

    def leakage(self, params: Any) -> Any:
        x_l = np.asarray(self["x_l"], float)
        rule = leakage_default(np.minimum(self["x_dpp"], self["x_qpp"]))
        return np.where(np.isnan(x_l), rule, x_l)

    def configure(self, plant: Any) -> None:
        p = plant.params
        if self.checked:
            if not (self["x_dpp"] < p.X_d_prime and self["x_qpp"] < p.X_q_prime):
                raise SimulationError("effect subtransient_dynamics: X''_d, X''_q must lie below X'_d, X'_q")
            if not self.leakage(p) < min(self["x_dpp"], self["x_qpp"]):
                raise SimulationError("effect subtransient_dynamics: X_l must lie below X''_d and X''_q")
        self._constants = self._gains(p)

    def _gains(self, p: Any) -> tuple[Any, ...]:
        """Once per plant: X_l, g_d, g_q and the two load factors on the transient windings."""
        x_l = self.leakage(p)
        xdp_l, xqp_l = p.X_d_prime - x_l, p.X_q_prime - x_l
        g_d = (self["x_dpp"] - x_l) / xdp_l
        g_q = (self["x_qpp"] - x_l) / xqp_l
        load_d = (p.X_d - p.X_d_prime) * (p.X_d_prime - self["x_dpp"]) / (xdp_l * xdp_l)
        load_q = (p.X_q - p.X_q_prime) * (p.X_q_prime - self["x_qpp"]) / (xqp_l * xqp_l)
        return x_l, g_d, g_q, load_d, load_q

    def initial_states(self, ctx: RotorContext, plant: Any) -> list[float]:
        # at rest a damper's drive is zero: its flux is the drive that psi_k = 0 would leave
        p, x_l = plant.params, self.leakage(plant.params)
        return list(damper_drives(ctx.e_q, ctx.e_d, 0.0, 0.0, ctx.i_d, ctx.i_q, p.X_d_prime - x_l, p.X_q_prime - x_l))

    def emf(self, x: Array, states: Array, params: Any) -> tuple[Array, Array, Any, Any]:
        _, g_d, g_q, _, _ = self._constants
        return damper_emf(g_d, x[2], states[0]), damper_emf(g_q, x[3], states[1]), self["x_dpp"], self["x_qpp"]

    def _drives(self, states: Array, ctx: RotorContext, params: Any) -> tuple[Array, Array]:
        x_l = self._constants[0]
        return damper_drives(
            ctx.e_q, ctx.e_d, states[0], states[1], ctx.i_d, ctx.i_q, params.X_d_prime - x_l, params.X_q_prime - x_l
        )

    def transient_losses(self, states: Array, ctx: RotorContext, params: Any) -> tuple[Any, Any]:
        d, q = self._drives(states, ctx, params)
        _, _, _, load_d, load_q = self._constants
        return load_d * d, load_q * q

    def derivatives(self, states: Array, ctx: RotorContext, params: Any) -> list[Array]:
        d, q = self._drives(states, ctx, params)
        return [d / self["t_d0pp"], q / self["t_q0pp"]]

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        x_l, g_d, g_q, load_d, load_q = self._constants
        p = plant.params
        terms = {k: self[k] for k in ("x_dpp", "x_qpp", "t_d0pp", "t_q0pp")}
        return {
            **terms,
            "xdp_l": p.X_d_prime - x_l,
            "xqp_l": p.X_q_prime - x_l,
            "g_d": g_d,
            "g_q": g_q,
            "load_d": load_d,
            "load_q": load_q,
        }
