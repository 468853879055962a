"""Equations (5)-(13) of the fourth-order generator model: the one place they are written.

State ``x = [delta, omega, E'_q, E'_d]`` (rad, pu, pu, pu). Each equation is one function of
plain arithmetic on its operands (:func:`rotor_angle` (5), :func:`swing` (6), :func:`field_d`
(7), :func:`field_q` (8), :func:`stator` (11)-(12), :func:`airgap_power`; (9)-(10) and (13) are
:mod:`~phid_ros.model.conventions`' ``dq_of`` and ``powers``). The operands may be floats or
numpy arrays, so the same functions serve three integrators:

- the validation play-in (numpy, many columns at once: :func:`derivatives`, :func:`currents`);
- the plant simulator (:mod:`phid_ros.sim.plant`, numpy), which adds the network's impedance
  to the stator's and the effects' terms through its typed hook;
- the compiled play-in (:mod:`phid_ros.sim.kernel`), which compiles these very functions with
  numba and calls them per column. Why no ``np.asarray`` or attribute access in them: numba
  compiles only what it can type, and a float operand must stay a float there.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ, omega_s
from phid_ros.model.parameters import PARAMETER_NAMES, GeneratorParameters

Array = NDArray[np.float64]
Value = Any  # a float or an array of them: the equations below take either, elementwise


@dataclass(frozen=True)
class Coefficients:
    """The constants of (5)-(8) and (11)-(12), worked out once per parameter set.

    Each is a float, or an array with one entry per column when many machines (or one machine
    on many scenarios) are integrated side by side, as the validation play-in does.
    """

    w_s: float
    inv_2h: Array
    d: Array  # D, zero in a column whose scenario ran without generator damping
    xd_diff: Array  # X_d - X'_d
    xq_diff: Array  # X_q - X'_q
    x_d_prime: Array
    x_q_prime: Array
    inv_td0: Array  # 1 / T'_d0: the integrators multiply, a division costs several times more
    inv_tq0: Array

    @classmethod
    def of(
        cls,
        params: GeneratorParameters | Sequence[GeneratorParameters] | Any,
        f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ,
        *,
        repeat: int = 1,
        damping: ArrayLike = 1.0,
    ) -> Coefficients:
        """From one set, or from several laid out as columns (``repeat`` times over, the sets
        varying fastest); ``damping`` (0 or 1 per column) switches D off where a run had none."""
        one = not isinstance(params, Sequence)  # one set, whose values may be arrays (one per column)
        sets: list[Any] = list(params) if isinstance(params, Sequence) else [params]
        col = {n: np.tile([getattr(p, n) for p in sets], repeat).astype(float) for n in PARAMETER_NAMES}
        if one and repeat == 1:
            col = {n: v[0] for n, v in col.items()}
        return cls(
            omega_s(f_nominal_hz),
            1.0 / (2.0 * col["H"]),
            col["D"] * np.asarray(damping, float),
            col["X_d"] - col["X_d_prime"],
            col["X_q"] - col["X_q_prime"],
            col["X_d_prime"],
            col["X_q_prime"],
            1.0 / col["T_d0_prime"],
            1.0 / col["T_q0_prime"],
        )


def rotor_angle(omega: Value, w_s: float) -> Value:
    """(5): d(delta)/dt = omega_s (omega - 1)."""
    return w_s * (omega - 1.0)


def swing(p_m: Value, p_e: Value, omega: Value, d: Value, inv_2h: Value) -> Value:
    """(6): d(omega)/dt = (P_m - P_e - D (omega - 1)) / 2H."""
    return (p_m - p_e - d * (omega - 1.0)) * inv_2h


def field_d(v_f: Value, e_q: Value, i_d: Value, xd_diff: Value, loss_d: Value, inv_td0: Value) -> Value:
    """(7): T'_d0 dE'_q/dt = V_f - E'_q - (X_d - X'_d) I_d, less the effects' ``loss_d`` (None: none)."""
    balance = v_f - e_q - xd_diff * i_d
    if loss_d is not None:
        balance = balance - loss_d
    return balance * inv_td0


def field_q(e_d: Value, i_q: Value, xq_diff: Value, loss_q: Value, inv_tq0: Value) -> Value:
    """(8): T'_q0 dE'_d/dt = -E'_d + (X_q - X'_q) I_q, less the effects' ``loss_q`` (None: none)."""
    balance = xq_diff * i_q - e_d
    if loss_q is not None:
        balance = balance - loss_q
    return balance * inv_tq0


def stator(e_q: Value, e_d: Value, v_d: Value, v_q: Value, r: Value, x_d: Value, x_q: Value) -> tuple[Value, Value]:
    """(I_d, I_q) from (11)-(12) behind a series resistance ``r``:
    ``E'_q - V_q = X'_d I_d + r I_q`` and ``V_d - E'_d = X'_q I_q - r I_d``.

    With ``r`` None (no resistance) these are the paper's ``I_d = (E'_q - V_q)/X'_d``,
    ``I_q = (V_d - E'_d)/X'_q``.
    The plant passes the stator resistance plus the network's, the reactances plus the
    network's, and the network's source voltage: the same equations solved with the network.
    """
    b_d = e_q - v_q
    b_q = v_d - e_d
    if r is None:  # no resistance (numba prunes this branch for a float r, numpy saves six array operations)
        return b_d / x_d, b_q / x_q
    det = x_d * x_q + r * r
    return (x_q * b_d - r * b_q) / det, (x_d * b_q + r * b_d) / det


def emf_behind(v_d: Value, v_q: Value, i_d: Value, i_q: Value, r: Value, x_d: Value, x_q: Value) -> tuple[Value, Value]:
    """(E'_q, E'_d) from the terminal values: (11)-(12) turned round, the inverse of :func:`stator`."""
    return v_q + x_d * i_d + r * i_q, v_d - x_q * i_q + r * i_d


def airgap_power(e_q: Value, e_d: Value, i_d: Value, i_q: Value, x_d: Value, x_q: Value) -> Value:
    """Power across the air gap behind (X'_d, X'_q): P_e of (13) when the stator has no resistance."""
    return e_d * i_d + e_q * i_q + (x_q - x_d) * i_d * i_q


def derivatives(
    x: Array, p_m: ArrayLike, p_e: ArrayLike, v_f: ArrayLike, i_d: Array, i_q: Array, c: Coefficients
) -> Array:
    """dx/dt from (5)-(8) with no effects. ``x`` holds its four states on the first axis, each of
    the same shape as the other inputs (no broadcasting: this runs at every stage of every
    integration step)."""
    _, omega, e_q, e_d = x
    return np.array(  # not np.stack: 3x its speed for four rows
        (
            rotor_angle(omega, c.w_s),
            swing(p_m, p_e, omega, c.d, c.inv_2h),
            field_d(v_f, e_q, i_d, c.xd_diff, None, c.inv_td0),
            field_q(e_d, i_q, c.xq_diff, None, c.inv_tq0),
        )
    )


def state_derivatives(
    x: ArrayLike,
    p_m: ArrayLike,
    p_e: ArrayLike,
    v_f: ArrayLike,
    i_d: ArrayLike,
    i_q: ArrayLike,
    params: GeneratorParameters,
    f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ,
) -> Array:
    """dx/dt from (5)-(8) for inputs that broadcast together; ``x`` has its four states on the first axis."""
    x = np.asarray(x, dtype=float)
    shape = np.broadcast_shapes(x.shape[1:], *(np.shape(a) for a in (p_m, p_e, v_f, i_d, i_q)))
    x = np.broadcast_to(x, (4, *shape))
    p_m, p_e, v_f, i_d, i_q = (np.broadcast_to(np.asarray(a, float), shape) for a in (p_m, p_e, v_f, i_d, i_q))
    return derivatives(x, p_m, p_e, v_f, i_d, i_q, Coefficients.of(params, f_nominal_hz))


def currents(e_q: Array, e_d: Array, v_d: Array, v_q: Array, c: Coefficients) -> tuple[Array, Array]:
    """(I_d, I_q) from (11)-(12) at the terminals (no stator resistance)."""
    return stator(e_q, e_d, v_d, v_q, None, c.x_d_prime, c.x_q_prime)


def stator_currents(
    e_q: ArrayLike, e_d: ArrayLike, v_d: ArrayLike, v_q: ArrayLike, params: GeneratorParameters
) -> tuple[Array, Array]:
    """(I_d, I_q) from (11)-(12) for one parameter set and any inputs."""
    e_q_, e_d_, v_d_, v_q_ = (np.asarray(a, float) for a in (e_q, e_d, v_d, v_q))
    return currents(e_q_, e_d_, v_d_, v_q_, Coefficients.of(params))


def reconstruct_fluxes(
    v_d: ArrayLike, v_q: ArrayLike, i_d: ArrayLike, i_q: ArrayLike, x_d_prime: ArrayLike, x_q_prime: ArrayLike
) -> tuple[Array, Array]:
    """Algebraic reconstruction (40)-(41): ``E'_q = V_q + X'_d I_d``, ``E'_d = V_d - X'_q I_q``."""
    vd, vq, id_, iq = (np.asarray(a, float) for a in (v_d, v_q, i_d, i_q))
    return emf_behind(vd, vq, id_, iq, 0.0, x_d_prime, x_q_prime)


def steady_state_field_voltage(e_q: ArrayLike, i_d: ArrayLike, params: GeneratorParameters) -> Array:
    """V_f that holds E'_q constant, (33): ``V_f = E'_q + (X_d - X'_d) I_d``."""
    return np.asarray(e_q, float) + (params.X_d - params.X_d_prime) * np.asarray(i_d, float)
