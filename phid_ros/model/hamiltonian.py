"""The Hamiltonian (1) and a consistent Port-Hamiltonian form of (5)-(8).

The paper's matrices (3)-(4) do not reproduce (5)-(8) as printed: with
``grad H = [0, 2H(omega-1), T'_d0 E'_q, T'_q0 E'_d]`` the entries of J and R
must carry the factors 1/(2H), 1/(2H)^2, 1/T'_d0^2, 1/T'_q0^2, and the input
vector needs the stator currents I_d, I_q as ports (the paper's ``u`` lacks
them). The form used here, derived from (1) and (5)-(8):

    J = [[0, w_s/(2H), 0, 0], [-w_s/(2H), 0, 0, 0], [0]*4, [0]*4]   (skew)
    R = diag(0, D/(2H)^2, 1/T'_d0^2, 1/T'_q0^2)                      (PSD)
    u = [P_m, P_e, V_f, I_d, I_q]
    g = [[0,      0,       0,        0,                 0              ],
         [1/(2H), -1/(2H), 0,        0,                 0              ],
         [0,      0,       1/T'_d0,  -(X_d-X'_d)/T'_d0, 0              ],
         [0,      0,       0,        0,                 (X_q-X'_q)/T'_q0]]

so that ``dx/dt = (J - R) grad H + g u`` is exactly (5)-(8), with the
conjugate output ``y = g^T grad H`` and the energy balance

    dH/dt = -grad H^T R grad H + u^T y  <=  u^T y   (passivity).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ, omega_s
from phid_ros.model.parameters import GeneratorParameters

Array = NDArray[np.float64]

PORT_NAMES: tuple[str, ...] = ("P_m", "P_e", "V_f", "I_d", "I_q")


@dataclass(frozen=True)
class HamiltonianValue:
    """ℋ(x) and its three stores (1): kinetic and the two magnetic energies."""

    kinetic: Array
    magnetic_d: Array  # T'_d0/2 E'_q^2, field (d-axis) winding
    magnetic_q: Array  # T'_q0/2 E'_d^2, q-axis rotor circuit

    @property
    def total(self) -> Array:
        return self.kinetic + self.magnetic_d + self.magnetic_q


def hamiltonian(omega: ArrayLike, e_q: ArrayLike, e_d: ArrayLike, params: GeneratorParameters) -> HamiltonianValue:
    """Equation (1): ``H(omega-1)^2 + T'_d0/2 E'_q^2 + T'_q0/2 E'_d^2``."""
    w = np.asarray(omega, float) - 1.0
    eq = np.asarray(e_q, float)
    ed = np.asarray(e_d, float)
    return HamiltonianValue(
        kinetic=params.H * w * w,
        magnetic_d=0.5 * params.T_d0_prime * eq * eq,
        magnetic_q=0.5 * params.T_q0_prime * ed * ed,
    )


def hamiltonian_gradient(x: ArrayLike, params: GeneratorParameters) -> Array:
    """∂ℋ/∂x for ``x = [delta, omega, E'_q, E'_d]`` on the first axis."""
    delta, omega, e_q, e_d = np.asarray(x, dtype=float)
    return np.stack(
        np.broadcast_arrays(
            np.zeros_like(delta),
            2.0 * params.H * (omega - 1.0),
            params.T_d0_prime * e_q,
            params.T_q0_prime * e_d,
        )
    )


def interconnection_matrix(params: GeneratorParameters, f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ) -> Array:
    j = np.zeros((4, 4))
    j[0, 1] = omega_s(f_nominal_hz) / (2.0 * params.H)
    j[1, 0] = -j[0, 1]
    return j


def dissipation_matrix(params: GeneratorParameters) -> Array:
    return np.diag([0.0, params.D / (2.0 * params.H) ** 2, 1.0 / params.T_d0_prime**2, 1.0 / params.T_q0_prime**2])


def input_matrix(params: GeneratorParameters) -> Array:
    p = params
    g = np.zeros((4, len(PORT_NAMES)))
    g[1, 0] = 1.0 / (2.0 * p.H)
    g[1, 1] = -1.0 / (2.0 * p.H)
    g[2, 2] = 1.0 / p.T_d0_prime
    g[2, 3] = -(p.X_d - p.X_d_prime) / p.T_d0_prime
    g[3, 4] = (p.X_q - p.X_q_prime) / p.T_q0_prime
    return g


def port_inputs(p_m: ArrayLike, p_e: ArrayLike, v_f: ArrayLike, i_d: ArrayLike, i_q: ArrayLike) -> Array:
    """``u`` stacked on the first axis, in the order of :data:`PORT_NAMES`."""
    return np.stack(np.broadcast_arrays(*(np.asarray(a, float) for a in (p_m, p_e, v_f, i_d, i_q))))


def ph_dynamics(
    x: ArrayLike, u: ArrayLike, params: GeneratorParameters, f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ
) -> Array:
    """``(J - R) ∇ℋ + g u``; equals :func:`phid_ros.model.equations.state_derivatives`."""
    grad = hamiltonian_gradient(x, params)
    jr = interconnection_matrix(params, f_nominal_hz) - dissipation_matrix(params)
    return np.tensordot(jr, grad, axes=1) + np.tensordot(input_matrix(params), np.asarray(u, float), axes=1)


@dataclass(frozen=True)
class PowerBalance:
    """Terms of ``dℋ/dt = -dissipation + supply``; ``margin = supply - dℋ/dt >= 0``."""

    dissipation: Array  # ∇ℋᵀ R ∇ℋ >= 0
    supply: Array  # uᵀ y with y = gᵀ ∇ℋ

    @property
    def dh_dt(self) -> Array:
        return self.supply - self.dissipation

    @property
    def passivity_margin(self) -> Array:
        return self.dissipation


def power_balance(x: ArrayLike, u: ArrayLike, params: GeneratorParameters) -> PowerBalance:
    grad = hamiltonian_gradient(x, params)
    r = dissipation_matrix(params)
    dissipation = np.einsum("i...,ij,j...->...", grad, r, grad)
    y = np.tensordot(input_matrix(params).T, grad, axes=1)
    supply = np.einsum("i...,i...->...", np.asarray(u, float), y)
    return PowerBalance(dissipation=dissipation, supply=supply)
