"""The network seen from the machine's terminals: its Thevenin reactance, from the recording.

Behind a reactance X_e from a source V_g the terminal phasor (V_t at angle zero) carries

    V_g = V_t - j X_e I = (V_t - X_e Q / V_t) - j X_e P / V_t,

so while V_g holds still, |V_g| worked out from the recorded V_t, P and Q with the right X_e
holds still too, whatever the machine did: an on-line reference step moves V_t by X_e per unit
of Q / V_t. X_e is the one that leaves |V_g| stillest over the scenario. It is determined where Q
moved and that X_e takes most of V_t's own movement out of |V_g| (the Mostar unit's four on-line
steps: X_e 0.120-0.121 pu, |V_g|'s spread 0.0002 pu against V_t's 0.002-0.023); elsewhere (no
load, a fault that changes the network, Q held still) it is not, and nothing is said to be.

The validation closes the voltage regulator's loop through it (:mod:`phid_ros.controls.closed_loop`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import uniform_filter1d

from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.terminal import at_no_load

Array = NDArray[np.float64]

X_E_MAX = 1.0  # pu on the machine's base: a unit behind more than this is not on a network
MIN_Q_MOVED = 0.02  # pu of Q / V_t over the scenario: less, and V_t's movement is not Q's doing
STILLER = 3.0  # |V_g| with X_e at least this many times stiller than V_t itself
SMOOTH_S = 0.1  # s: the moving mean V_t, P and Q are compared through


@dataclass(frozen=True)
class NetworkEquivalent:
    """The network's reactance seen from the terminals and how well it explains the recording."""

    x_e: float  # pu on the machine's base
    source_spread: float  # std of |V_g| over the scenario with x_e (pu; through SMOOTH_S's moving mean)
    terminal_spread: float  # std of V_t itself (pu, the same way): |V_g| with no reactance

    def describe(self) -> str:
        return (
            f"the network behind X_e = {self.x_e:.3f} pu (from the recording: its source's |V_g| moves "
            f"{self.source_spread:.2g} pu where V_t moved {self.terminal_spread:.2g})"
        )


def source_magnitude(v_t: Array, p_e: Array, q_e: Array, x_e: float) -> Array:
    """|V_g| behind ``x_e`` from the terminal's V_t, P and Q."""
    return np.hypot(v_t - x_e * q_e / v_t, x_e * p_e / v_t)


def thevenin_reactance(s: ScenarioData) -> NetworkEquivalent | None:
    """The scenario's network reactance, or None where the recording does not determine it (see
    the module's note)."""
    from scipy.optimize import minimize_scalar

    if not s.has("v_t", "p_e", "q_e") or at_no_load(s):
        return None
    v, p, q = (np.asarray(s[c], float) for c in ("v_t", "p_e", "q_e"))
    if not (np.isfinite(v).all() and np.isfinite(p).all() and np.isfinite(q).all()) or np.min(v) <= 0.1:
        return None
    # the sensors' noise moves |V_g| whatever X_e: averaged out, the stillness is the network's
    # (ANDES's IEEET1 unit's V_ref step: V_t's noise left |V_g| 2.9 times stiller than V_t, 3 asked)
    width = max(1, int(round(SMOOTH_S / s.dt)))
    v, p, q = (uniform_filter1d(x, width, mode="nearest") for x in (v, p, q))
    if float(np.ptp(q / v)) < MIN_Q_MOVED:
        return None
    found = minimize_scalar(
        lambda x: float(np.std(source_magnitude(v, p, q, x))),
        bounds=(0.0, X_E_MAX),
        method="bounded",
        options={"xatol": 1e-4},
    )
    x_e = float(found.x)
    spread, own = float(found.fun), float(np.std(v))
    if x_e >= 0.99 * X_E_MAX or x_e <= 1e-3 or spread * STILLER > own:
        return None
    return NetworkEquivalent(x_e, spread, own)
