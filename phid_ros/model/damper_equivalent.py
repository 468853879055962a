"""One rotor axis with GENROU's damper, and the fourth-order axis that plays its slow part.

The paper's fourth-order model has one circuit per axis: X, X', T'_0. GENROU has two, the
field (or q-axis transient) winding and a damper, written with the classical constants X, X',
X'', X_l, T'_0, T''_0 (:class:`phid_ros.sim.effects.subtransient_dynamics.SubtransientDynamics`
holds its equations). The damper's current loads the transient winding, so GENROU's slow pole is
not 1/T'_0 and its slow reactance drop is not X - X': a fourth-order fit of a GENROU machine
finds the slow pole and the slow drop, and writing those back as GENROU's X', T'_0 builds
another machine (on ANDES's GENROU, with X'' 2 % below X'_q, T'_q0 came out 4 % above
GENROU's constant and X'_q 1.4 % below, both correct for the fourth-order model).

The operational reactance of the axis (field voltage held), with a = X' - X_l,
g = (X'' - X_l)/a and the load L = (X - X')(X' - X'')/a^2, is

    X(s) = X'' + r_1/(1 + s tau_1) + r_2/(1 + s tau_2)

with tau_1 > tau_2 the roots of T'_0 T''_0 s^2 + (T'_0 + T''_0 + L T''_0) s + 1 (open circuit).
The fourth-order axis that plays the slow part is X' = X - r_1, T'_0 = tau_1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from phid_ros.errors import ParameterError

# relative: a damper whose X'' lies this close to X' changes neither the slow pole nor its drop
INERT = 1e-9


@dataclass(frozen=True)
class DamperedAxis:
    """One axis of GENROU, by its classical constants (pu, s)."""

    x: float  # X_d or X_q
    x_t: float  # X'_d or X'_q
    x_pp: float  # X'' (GENROU's X''_d = X''_q)
    x_l: float  # stator leakage
    t_0: float  # T'_d0 or T'_q0
    t_0pp: float  # T''_d0 or T''_q0

    def __post_init__(self) -> None:
        if not (0 < self.x_l < self.x_pp <= self.x_t < self.x):
            raise ParameterError(
                f"a dampered axis needs 0 < X_l < X'' <= X' < X, got X_l={self.x_l:g}, X''={self.x_pp:g}, "
                f"X'={self.x_t:g}, X={self.x:g}"
            )
        if not (self.t_0 > 0 and self.t_0pp > 0):
            raise ParameterError(f"time constants must be positive, got T'_0={self.t_0:g}, T''_0={self.t_0pp:g}")

    @property
    def damper_acts(self) -> bool:
        return self.x_pp < self.x_t * (1 - INERT)

    def fourth_order(self) -> tuple[float, float]:
        """(X', T'_0) of the fourth-order axis with the same slow pole and slow reactance drop."""
        if not self.damper_acts:
            return self.x_t, self.t_0
        a = self.x_t - self.x_l
        g = (self.x_pp - self.x_l) / a
        load = (self.x - self.x_t) * (self.x_t - self.x_pp) / a**2
        # states (E', psi_k), input I, output psi'' - X'' I = -X(s) I: the equations of
        # SubtransientDynamics with the field voltage held
        a_mat = np.array([[-(1 + load) / self.t_0, load / self.t_0], [1 / self.t_0pp, -1 / self.t_0pp]])
        b = np.array([(load * a - (self.x - self.x_t)) / self.t_0, -a / self.t_0pp])
        c = np.array([g, 1 - g])
        poles, v = np.linalg.eig(a_mat)
        poles, v = np.real(poles), np.real(v)  # two real poles: the matrix is similar to a symmetric one
        w = np.linalg.inv(v)
        slow = int(np.argmax(poles))  # the pole nearest zero
        # -X(s) = -X'' + sum (c v_i)(w_i b)/(s - p_i), and r_i/(1 + s tau_i) = -r_i p_i/(s - p_i)
        r_1 = float((c @ v[:, slow]) * (w[slow] @ b)) / poles[slow]
        return float(self.x - r_1), float(-1.0 / poles[slow])

    def for_fourth_order(self, x_t: float, t_0: float) -> DamperedAxis:
        """This axis (X, X'', X_l, T''_0 kept) with the classical X', T'_0 whose slow part is the
        fourth-order axis (``x_t``, ``t_0``): what a GENROU record must carry to play it.

        Raises :class:`ParameterError` where no GENROU constants reach it (X' would have to
        reach X, or the fourth-order X' lies at or below X'')."""
        if not self.x_pp < x_t < self.x:
            raise ParameterError(f"a fourth-order X'={x_t:g} must lie between X''={self.x_pp:g} and X={self.x:g}")
        from scipy.optimize import least_squares  # the export's only use of it: imported when needed

        span = self.x - self.x_pp

        def miss(z: np.ndarray) -> np.ndarray:
            axis = replace(self, x_t=self.x_pp + span * _unit(z[0]), t_0=t_0 * math.exp(z[1]))
            got_x, got_t = axis.fourth_order()
            return np.array([(got_x - x_t) / span, math.log(got_t / t_0)])

        start = np.array([_logit((x_t - self.x_pp) / span), 0.0])
        fit = least_squares(miss, start, xtol=1e-14, ftol=1e-14, gtol=1e-14)
        if not np.all(np.abs(fit.fun) < 1e-8):
            raise ParameterError(
                f"no GENROU axis with X''={self.x_pp:g}, T''_0={self.t_0pp:g} s plays the fourth-order "
                f"X'={x_t:g}, T'_0={t_0:g} s (closest misses by {np.max(np.abs(fit.fun)):.2g})"
            )
        return replace(self, x_t=self.x_pp + span * _unit(fit.x[0]), t_0=t_0 * math.exp(fit.x[1]))


def _unit(z: float) -> float:
    return 1.0 / (1.0 + math.exp(-z))


def _logit(p: float) -> float:
    p = min(max(p, 1e-12), 1 - 1e-12)
    return math.log(p / (1 - p))
