"""The plant: fourth-order generator (5)-(8) behind the network of :mod:`network`.

Integration is fixed-step RK4 (dt <= 1 ms) vectorised over scenarios: every
array carries one column per scenario, so a whole catalogue costs one Python
loop over time. Inputs (P_m, V_f, the network's Thevenin pair) are held
constant over each step, so a disturbance at a sample instant is exact.

The equations are :mod:`phid_ros.model.equations`' (5)-(13), called here with the
network's impedance added to the stator's; the effects (saturation, damper windings,
shaft torsion, ...) add states after the four base states and terms through their hooks,
which read one typed :class:`~phid_ros.sim.effects.RotorContext`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import SimulationError
from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ, dq_of, electrical_power
from phid_ros.model.equations import (
    Coefficients,
    airgap_power,
    emf_behind,
    field_d,
    field_q,
    rotor_angle,
    stator,
    swing,
)
from phid_ros.model.parameters import GeneratorParameters
from phid_ros.numerics import rk4
from phid_ros.sim.effects import PlantEffect, RotorContext, leakage_default
from phid_ros.sim.network import Network, terminal_dq

Array = NDArray[np.float64]
MAX_DT = 1e-3


@dataclass(frozen=True)
class OperatingPoint:
    """Pre-disturbance terminal condition (paper: 0.8 pu active power at 1.0 pu voltage)."""

    p_e: float = 0.8
    v_t: float = 1.0
    q_e: float = 0.4  # pf 0.89 lagging: keeps the +0.15 pu torque step and 200 ms fault stable


@dataclass(frozen=True)
class SteadyState:
    delta: float
    e_q: float
    e_d: float
    v_f: float
    p_m: float
    i_d: float
    i_q: float
    v_d: float
    v_q: float
    theta_t: float
    v_inf: float  # infinite-bus magnitude; its angle is the reference, 0
    extra: tuple[float, ...] = ()  # states of switched-on effects, after the four base states

    @property
    def x(self) -> Array:
        return np.array([self.delta, 1.0, self.e_q, self.e_d, *self.extra])


@dataclass(frozen=True)
class Inputs:
    """Per-step inputs, shape (n_steps, n_scenarios); ``damping`` is D per scenario."""

    p_m: Array
    v_f: Array
    v_th_abs: Array
    v_th_angle: Array
    r_th: Array
    x_th: Array
    damping: Array

    @property
    def n_steps(self) -> int:
        return int(self.p_m.shape[0])


@dataclass(frozen=True)
class Trajectory:
    """States and terminal quantities at every step, shape (n_steps + 1, n_scenarios)."""

    t: Array
    delta: Array
    omega: Array
    e_q: Array
    e_d: Array
    i_d: Array
    i_q: Array
    v_d: Array
    v_q: Array
    v_t: Array
    theta_t: Array
    p_e: Array
    q_e: Array
    p_m: Array
    v_f: Array

    def channels(self) -> dict[str, Array]:
        """The ten sensor channels (true values)."""
        return {
            name: getattr(self, name)
            for name in ("v_t", "theta_t", "i_d", "i_q", "omega", "delta", "v_f", "p_m", "p_e", "q_e")
        }


class Plant:
    def __init__(
        self,
        params: GeneratorParameters,
        network: Network | None = None,
        *,
        f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ,
        r_a: float = 0.0,
        effects: tuple = (),
    ) -> None:
        if f_nominal_hz <= 0:
            raise SimulationError(f"nominal frequency must be positive, got {f_nominal_hz}")
        self.params = params
        self.network = network or Network()
        self.f_nominal_hz = float(f_nominal_hz)
        self.r_a = float(r_a)
        self.effects = tuple(effects)
        # the equations' constants, once per plant (the compiled kernel reads them too): _rhs runs
        # millions of times in a diagnosis, and recomputing them there was a sixth of its time
        p = params
        self.coef = Coefficients.of(params, self.f_nominal_hz)  # its D is unused: D comes per run
        self.ws = self.coef.w_s
        self.slots: list[slice] = []
        start = 4
        for effect in self.effects:
            effect.configure(self)
            self.slots.append(slice(start, start + len(effect.state_names)))
            start += len(effect.state_names)
        self.n_states = start
        self._loss_effects = [
            (e, sl)
            for e, sl in zip(self.effects, self.slots)
            if type(e).transient_losses is not PlantEffect.transient_losses
        ]
        emf_owners = [e for e in self.effects if e.provides_emf]
        if len(emf_owners) > 1:
            raise SimulationError("only one effect may replace the stator EMF")
        # X_l, which GENROU's rotor equations assume: the damper model's, else the planning default
        owned = [x for x in (e.leakage(p) for e in emf_owners) if x is not None]
        self.x_l = owned[0] if owned else leakage_default(np.minimum(p.X_d_prime, p.X_q_prime))

    # -- steady state ---------------------------------------------------
    def steady_state(self, op: OperatingPoint) -> SteadyState:
        """Equilibrium with ω = 1 that delivers ``op`` at the terminals; dx/dt = 0 there.

        Without effects on the q axis the rotor lies on E_Q = V + (R_a + jX_q) I. An effect that
        loads the q-axis transient winding in steady state (GENROU's saturation) moves it; the
        angle is then found by a secant search on the q-axis balance (E'_d's derivative zero).
        """
        p = self.params
        if op.v_t <= 0:
            raise SimulationError(f"operating point voltage must be positive, got {op.v_t}")
        v = complex(op.v_t, 0.0)
        i = complex(op.p_e, -op.q_e) / op.v_t
        v_inf = v - self.network.z_e * i
        ref = float(np.angle(v_inf))

        def at(delta_t: float) -> tuple[RotorContext, complex, tuple[float, ...], float, float]:
            """The rotor at angle ``delta_t`` from the terminal phasor: its context, the terminal
            voltage in d/q, effect states and the residual losses (d, q) the transient windings carry."""
            i_dq = 1j * i * np.exp(-1j * delta_t)
            v_dq = 1j * v * np.exp(-1j * delta_t)
            i_d, i_q, v_d, v_q = i_dq.real, i_dq.imag, v_dq.real, v_dq.imag
            ctx = self.rest_context(delta_t - ref, 1.0, i_d, i_q, v_d, v_q)
            extra = tuple(float(v) for v in self.rest_states(ctx))
            x = np.array([delta_t - ref, 1.0, ctx.e_q, ctx.e_d, *extra])
            psi_d, psi_q, _, _ = self._emf(x)
            ctx = replace(ctx, psi_d=psi_d, psi_q=psi_q)
            loss_d, loss_q = self._transient_losses(x, ctx)
            return ctx, complex(v_d, v_q), extra, float(loss_d), float(loss_q)

        def q_balance(delta_t: float) -> float:
            ctx, _, _, _, loss_q = at(delta_t)
            return float(field_q(ctx.e_d, ctx.i_q, self.coef.xq_diff, loss_q, 1.0))

        delta_t = float(np.angle(v + complex(self.r_a, p.X_q) * i))  # rotor angle relative to the terminal
        if self._loss_effects:
            a, fa = delta_t, q_balance(delta_t)
            b = a + 1e-3
            for _ in range(50):
                fb = q_balance(b)
                if abs(fb) < 1e-13 or fb == fa:
                    break
                a, fa, b = b, fb, b - fb * (b - a) / (fb - fa)
            delta_t = b
        ctx, v_dq, extra, loss_d, _ = at(delta_t)
        return SteadyState(
            delta=delta_t - ref,
            e_q=float(ctx.e_q),
            e_d=float(ctx.e_d),
            v_f=float(ctx.e_q + self.coef.xd_diff * ctx.i_d + loss_d),  # (7) at rest
            p_m=float(ctx.p_m),
            i_d=float(ctx.i_d),
            i_q=float(ctx.i_q),
            v_d=v_dq.real,
            v_q=v_dq.imag,
            theta_t=-ref,
            v_inf=float(abs(v_inf)),
            extra=extra,
        )

    def rest_context(self, delta: Any, omega: Any, i_d: Any, i_q: Any, v_d: Any, v_q: Any) -> RotorContext:
        """The effects' view of the machine at rest with these terminal values: the fluxes from
        (11)-(12) turned round, P_m equal to the air-gap power, and (before the effects' states
        exist) the fourth-order flux behind the stator. Floats, or arrays of one per column."""
        c = self.coef
        e_q, e_d = emf_behind(v_d, v_q, i_d, i_q, self.r_a, c.x_d_prime, c.x_q_prime)
        p_m = airgap_power(e_q, e_d, i_d, i_q, c.x_d_prime, c.x_q_prime)
        return RotorContext(delta, omega, e_q, e_d, i_d, i_q, e_q, e_d, p_m, p_m, 0.0, self.x_l, self.ws)

    def rest_states(self, ctx: RotorContext) -> list[Any]:
        """The switched-on effects' states at rest (after the four base states)."""
        return [v for effect in self.effects for v in effect.initial_states(ctx, self)]

    # -- equations --------------------------------------------------------
    def _emf(self, x: Array) -> tuple[Array, Array, float, float]:
        """The EMF behind the stator reactances: (E'_q, E'_d, X'_d, X'_q), or an effect's (E''...)."""
        p = self.params
        for effect, sl in zip(self.effects, self.slots):
            if effect.provides_emf:
                return effect.emf(x, x[sl], p)
        return x[2], x[3], p.X_d_prime, p.X_q_prime

    def _currents(
        self,
        delta: Array,
        e_q: Array,
        e_d: Array,
        v_abs: Array,
        v_ang: Array,
        r_th: Array,
        x_th: Array,
        x_d_int: Any = None,
        x_q_int: Any = None,
    ) -> tuple[Array, Array, Array, Array]:
        """(I_d, I_q) from the stator (11)-(12) and the network together, and the network's source
        voltage in d/q: the stator's equations with the network's impedance added to its own."""
        p = self.params
        xdi = p.X_d_prime if x_d_int is None else x_d_int
        xqi = p.X_q_prime if x_q_int is None else x_q_int
        vth_d, vth_q = dq_of(v_abs, delta - v_ang)
        i_d, i_q = stator(e_q, e_d, vth_d, vth_q, r_th + self.r_a, xdi + x_th, xqi + x_th)
        return i_d, i_q, vth_d, vth_q

    def _rhs(
        self, x: Array, p_m: Array, v_f: Array, v_abs: Array, v_ang: Array, r_th: Array, x_th: Array, damping: Array
    ) -> Array:
        c = self.coef
        delta, omega, e_q, e_d = x[0], x[1], x[2], x[3]
        eq_i, ed_i, xd_i, xq_i = self._emf(x) if self.effects else (e_q, e_d, c.x_d_prime, c.x_q_prime)
        i_d, i_q, _, _ = self._currents(delta, eq_i, ed_i, v_abs, v_ang, r_th, x_th, xd_i, xq_i)
        p_airgap = airgap_power(eq_i, ed_i, i_d, i_q, xd_i, xq_i)  # P_e (13) when R_a = 0
        if not self.effects:
            return np.array(  # 3x faster than np.stack for a handful of rows, same values
                [
                    rotor_angle(omega, c.w_s),
                    swing(p_m, p_airgap, omega, damping, c.inv_2h),
                    field_d(v_f, e_q, i_d, c.xd_diff, None, c.inv_td0),
                    field_q(e_d, i_q, c.xq_diff, None, c.inv_tq0),
                ]
            )
        ctx = RotorContext(delta, omega, e_q, e_d, i_d, i_q, eq_i, ed_i, p_m, p_airgap, damping, self.x_l, self.ws)
        loss_d, loss_q = self._transient_losses(x, ctx)
        derivs = [
            rotor_angle(omega, c.w_s),
            swing(p_m, p_airgap, omega, damping, c.inv_2h),
            field_d(v_f, e_q, i_d, c.xd_diff, loss_d, c.inv_td0),
            field_q(e_d, i_q, c.xq_diff, loss_q, c.inv_tq0),
        ]
        for effect, sl in zip(self.effects, self.slots):
            replaced = effect.swing(x[sl], ctx, self.params)
            if replaced is not None:
                derivs[1] = replaced
            derivs.extend(effect.derivatives(x[sl], ctx, self.params))
        return np.array(derivs)

    def _transient_losses(self, x: Array, ctx: RotorContext) -> tuple[Any, Any]:
        """Terms the switched-on effects subtract in the two transient windings' equations."""
        loss_d: Any = 0.0
        loss_q: Any = 0.0
        for effect, sl in self._loss_effects:
            d, q = effect.transient_losses(x[sl], ctx, self.params)
            loss_d, loss_q = loss_d + d, loss_q + q
        return loss_d, loss_q

    def derivatives(self, x: Array, inputs: Inputs, step: int = 0) -> Array:
        """dx/dt for states ``x`` (4, n) under the inputs of one step."""
        k = step
        return self._rhs(
            np.asarray(x, float),
            inputs.p_m[k],
            inputs.v_f[k],
            inputs.v_th_abs[k],
            inputs.v_th_angle[k],
            inputs.r_th[k],
            inputs.x_th[k],
            inputs.damping,
        )

    # -- integration ------------------------------------------------------
    def simulate(self, x0: Array, inputs: Inputs, dt: float) -> Trajectory:
        """RK4 from ``x0`` (n_states, n) over ``inputs``; returns states and terminal quantities."""
        if not 0.0 < dt <= MAX_DT + 1e-15:
            raise SimulationError(f"time step must be in (0, {MAX_DT}] s, got {dt}")
        u = inputs
        d = u.damping

        def at_step(k: int) -> tuple:
            return (u.p_m[k], u.v_f[k], u.v_th_abs[k], u.v_th_angle[k], u.r_th[k], u.x_th[k], d)

        states = rk4(self._rhs, np.asarray(x0, dtype=float), u.n_steps, dt, at_step)
        if not np.all(np.isfinite(states)):
            raise SimulationError("simulation diverged (non-finite state); the scenario is unstable or dt too large")
        return self._terminal_quantities(states, inputs, dt)

    def _terminal_quantities(self, states: Array, inputs: Inputs, dt: float) -> Trajectory:
        n = states.shape[0]

        # the sample at step k sees the inputs of step k; the last sample keeps the last inputs
        def at_samples(a: Array) -> Array:
            return np.concatenate((a, a[-1:]), axis=0)[:n]

        v_abs, v_ang = at_samples(inputs.v_th_abs), at_samples(inputs.v_th_angle)
        r_th, x_th = at_samples(inputs.r_th), at_samples(inputs.x_th)
        delta, omega, e_q, e_d = (states[:, i] for i in range(4))
        eq_i, ed_i, xd_i, xq_i = self._emf(np.moveaxis(states, 1, 0))
        i_d, i_q, vth_d, vth_q = self._currents(delta, eq_i, ed_i, v_abs, v_ang, r_th, x_th, xd_i, xq_i)
        v_d, v_q = terminal_dq(vth_d, vth_q, i_d, i_q, r_th, x_th)
        p_e, q_e = electrical_power(v_d, v_q, i_d, i_q)
        return Trajectory(
            t=np.arange(n, dtype=np.float64) * dt,
            delta=delta,
            omega=omega,
            e_q=e_q,
            e_d=e_d,
            i_d=i_d,
            i_q=i_q,
            v_d=v_d,
            v_q=v_q,
            v_t=np.hypot(v_d, v_q),
            theta_t=delta - np.arctan2(v_d, v_q),
            p_e=p_e,
            q_e=q_e,
            p_m=at_samples(inputs.p_m),
            v_f=at_samples(inputs.v_f),
        )
