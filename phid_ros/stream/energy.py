"""The Hamiltonian (1) on the reconstructed state, with its energy balance, for monitoring.

The state is reconstructed from terminal quantities with the current parameters:
omega measured, E'_q = V_q + X'_d I_d and E'_d = V_d - X'_q I_q (40)-(41);
u = [P_m, P_e, V_f, I_d, I_q] measured. The passivity margin is the dissipation
grad H^T R grad H (>= 0), the gap between the supplied power and dH/dt.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from phid_ros.model.channels import CHANNEL_INDEX
from phid_ros.model.conventions import terminal_to_dq
from phid_ros.model.equations import reconstruct_fluxes
from phid_ros.model.hamiltonian import hamiltonian, port_inputs, power_balance
from phid_ros.model.parameters import GeneratorParameters


@dataclass
class EnergySamples:
    t_ns: NDArray[np.int64]
    value: NDArray[np.float64]
    kinetic: NDArray[np.float64]
    magnetic_d: NDArray[np.float64]
    magnetic_q: NDArray[np.float64]
    dissipation: NDArray[np.float64]
    supply: NDArray[np.float64]
    passivity_margin: NDArray[np.float64]
    delta: NDArray[np.float64]
    omega: NDArray[np.float64]
    e_q_prime: NDArray[np.float64]
    e_d_prime: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.t_ns)


def energy(t_ns: NDArray[np.int64], values: NDArray[np.float64], params: GeneratorParameters) -> EnergySamples:
    """ℋ and its balance at each given aligned sample (vectorised)."""
    col = lambda c: values[:, CHANNEL_INDEX[c]]  # noqa: E731
    v_d, v_q = terminal_to_dq(col("v_t"), col("delta"), col("theta_t"))
    e_q, e_d = reconstruct_fluxes(v_d, v_q, col("i_d"), col("i_q"), params.X_d_prime, params.X_q_prime)
    h = hamiltonian(col("omega"), e_q, e_d, params)
    x = np.stack([col("delta"), col("omega"), e_q, e_d])
    bal = power_balance(x, port_inputs(col("p_m"), col("p_e"), col("v_f"), col("i_d"), col("i_q")), params)
    return EnergySamples(
        t_ns,
        h.total,
        h.kinetic,
        h.magnetic_d,
        h.magnetic_q,
        bal.dissipation,
        bal.supply,
        bal.passivity_margin,
        col("delta"),
        col("omega"),
        e_q,
        e_d,
    )
