"""Equations (5)-(13) of the fourth-order generator model, vectorised with numpy.

State ``x = [delta, omega, E'_q, E'_d]`` (rad, pu, pu, pu). All functions accept
scalars or arrays that broadcast together.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ, omega_s
from phid_ros.model.parameters import GeneratorParameters

Array = NDArray[np.float64]


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
    """dx/dt from (5)-(8); ``x`` has its four states on the first axis."""
    _, omega, e_q, e_d = np.asarray(x, dtype=float)
    p = params
    d_delta = (omega - 1.0) * omega_s(f_nominal_hz)
    d_omega = (np.asarray(p_m) - np.asarray(p_e) - p.D * (omega - 1.0)) / (2.0 * p.H)
    d_eq = (np.asarray(v_f) - e_q - (p.X_d - p.X_d_prime) * np.asarray(i_d)) / p.T_d0_prime
    d_ed = (-e_d + (p.X_q - p.X_q_prime) * np.asarray(i_q)) / p.T_q0_prime
    return np.stack(np.broadcast_arrays(d_delta, d_omega, d_eq, d_ed))


def stator_currents(
    e_q: ArrayLike, e_d: ArrayLike, v_d: ArrayLike, v_q: ArrayLike, params: GeneratorParameters
) -> tuple[Array, Array]:
    """(I_d, I_q) from (11)-(12): ``I_d = (E'_q - V_q)/X'_d``, ``I_q = (V_d - E'_d)/X'_q``."""
    i_d = (np.asarray(e_q, float) - np.asarray(v_q, float)) / params.X_d_prime
    i_q = (np.asarray(v_d, float) - np.asarray(e_d, float)) / params.X_q_prime
    return i_d, i_q


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
