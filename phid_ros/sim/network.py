"""The grid seen by the generator: step-up transformer and line to an infinite bus.

We use a Thevenin equivalent (our choice, allowed by the issue): the generator
terminal bus connects through ``Z_e = R_e + j(X_T + X_L)`` to an infinite bus of
voltage ``V_inf`` at angle 0 (the synchronous reference frame). A three-phase
fault at the generator terminal bus through ``Z_f`` turns the network into the
Thevenin pair ``V_th = V_inf Z_f/(Z_f + Z_e)``, ``Z_th = Z_e Z_f/(Z_e + Z_f)``,
so the same algebraic solve covers healthy and faulted periods.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from phid_ros.errors import SimulationError


@dataclass(frozen=True)
class Network:
    x_transformer: float = 0.12  # pu on machine base (1000 MVA step-up transformer)
    x_line: float = 0.08  # pu, line plus the grid's short-circuit reactance
    r_line: float = 0.0  # pu; kept at 0 so grid losses do not hide in P_e

    def __post_init__(self) -> None:
        if self.x_transformer < 0 or self.x_line < 0 or self.r_line < 0:
            raise SimulationError(f"network impedances must be non-negative, got {self}")
        if self.x_transformer + self.x_line <= 0:
            raise SimulationError("network reactance X_T + X_L must be positive")

    @property
    def z_e(self) -> complex:
        return complex(self.r_line, self.x_transformer + self.x_line)

    def thevenin(
        self, v_inf: ArrayLike, fault_impedance: ArrayLike | None = None
    ) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """(V_th, Z_th) seen from the terminal bus; ``fault_impedance`` NaN or None means healthy."""
        v = np.asarray(v_inf, dtype=complex)
        ze = self.z_e
        if fault_impedance is None:
            return v, np.full(v.shape, ze, dtype=complex)
        zf = np.asarray(fault_impedance, dtype=complex)
        healthy = np.isnan(zf)
        zf_safe = np.where(healthy, 1.0, zf)
        v_th = np.where(healthy, v, v * zf_safe / (zf_safe + ze))
        z_th = np.where(healthy, ze, ze * zf_safe / (ze + zf_safe))
        return v_th, z_th


def terminal_dq(vth_d: Any, vth_q: Any, i_d: Any, i_q: Any, r_th: Any, x_th: Any) -> tuple[Any, Any]:
    """(V_d, V_q) at the terminal bus: the source's voltage plus the drop the stator current
    drives back through the network's ``R_th + j X_th`` (floats or arrays)."""
    return vth_d + r_th * i_d - x_th * i_q, vth_q + r_th * i_q + x_th * i_d
