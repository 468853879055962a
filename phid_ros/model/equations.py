"""Equations (5)-(13) of the fourth-order generator model, vectorised with numpy.

State ``x = [delta, omega, E'_q, E'_d]`` (rad, pu, pu, pu). (5)-(8) and (11)-(12) are written
once, in :func:`derivatives` and :func:`currents`; the validation play-in integrates them over
many columns at once. The plant simulator (:mod:`phid_ros.sim.plant`) and its compiled kernel
extend them with the network and the effects, and tests hold them to these.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ, omega_s
from phid_ros.model.parameters import PARAMETER_NAMES, GeneratorParameters

Array = NDArray[np.float64]


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
    t_d0_prime: Array
    t_q0_prime: Array

    @classmethod
    def of(
        cls,
        params: GeneratorParameters | Sequence[GeneratorParameters],
        f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ,
        *,
        repeat: int = 1,
        damping: ArrayLike = 1.0,
    ) -> Coefficients:
        """From one set, or from several laid out as columns (``repeat`` times over, the sets
        varying fastest); ``damping`` (0 or 1 per column) switches D off where a run had none."""
        sets = [params] if isinstance(params, GeneratorParameters) else list(params)
        col = {n: np.tile([getattr(p, n) for p in sets], repeat).astype(float) for n in PARAMETER_NAMES}
        if isinstance(params, GeneratorParameters) and repeat == 1:
            col = {n: v[0] for n, v in col.items()}
        return cls(
            omega_s(f_nominal_hz),
            1.0 / (2.0 * col["H"]),
            col["D"] * np.asarray(damping, float),
            col["X_d"] - col["X_d_prime"],
            col["X_q"] - col["X_q_prime"],
            col["X_d_prime"],
            col["X_q_prime"],
            col["T_d0_prime"],
            col["T_q0_prime"],
        )


def derivatives(
    x: Array, p_m: ArrayLike, p_e: ArrayLike, v_f: ArrayLike, i_d: Array, i_q: Array, c: Coefficients
) -> Array:
    """dx/dt from (5)-(8): the one place they are written. ``x`` holds its four states on the
    first axis, each of the same shape as the other inputs (no broadcasting: this runs at every
    stage of every integration step)."""
    _, omega, e_q, e_d = x
    slip = omega - 1.0
    return np.array(  # not np.stack: 3x its speed for four rows
        (
            c.w_s * slip,  # (5)
            (p_m - p_e - c.d * slip) * c.inv_2h,  # (6)
            (v_f - e_q - c.xd_diff * i_d) / c.t_d0_prime,  # (7)
            (c.xq_diff * i_q - e_d) / c.t_q0_prime,  # (8)
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
    """(I_d, I_q) from (11)-(12), the one place they are written: ``I_d = (E'_q - V_q)/X'_d``,
    ``I_q = (V_d - E'_d)/X'_q``."""
    return (e_q - v_q) / c.x_d_prime, (v_d - e_d) / c.x_q_prime


def stator_currents(
    e_q: ArrayLike, e_d: ArrayLike, v_d: ArrayLike, v_q: ArrayLike, params: GeneratorParameters
) -> tuple[Array, Array]:
    """(I_d, I_q) from (11)-(12) for one parameter set and any inputs."""
    return currents(*(np.asarray(a, float) for a in (e_q, e_d, v_d, v_q)), Coefficients.of(params))


def reconstruct_fluxes(
    v_d: ArrayLike, v_q: ArrayLike, i_d: ArrayLike, i_q: ArrayLike, x_d_prime: float, x_q_prime: float
) -> tuple[Array, Array]:
    """Algebraic reconstruction (40)-(41): ``E'_q = V_q + X'_d I_d``, ``E'_d = V_d - X'_q I_q``."""
    e_q = np.asarray(v_q, float) + x_d_prime * np.asarray(i_d, float)
    e_d = np.asarray(v_d, float) - x_q_prime * np.asarray(i_q, float)
    return e_q, e_d


def steady_state_field_voltage(e_q: ArrayLike, i_d: ArrayLike, params: GeneratorParameters) -> Array:
    """V_f that holds E'_q constant, (33): ``V_f = E'_q + (X_d - X'_d) I_d``."""
    return np.asarray(e_q, float) + (params.X_d - params.X_d_prime) * np.asarray(i_d, float)
