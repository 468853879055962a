"""IEEE Std 115 baseline (paper section 3.2): short-circuit current envelope fits.

d axis: I(t) = E [1/X'_d exp(-t/T'_d) + 1/X_d] fitted to the stator current
magnitude from fault inception (15), bounds (18), weights proportional to the
fault duration (19), differential evolution; T'_d0 = T'_d X_d / X'_d (16).
q axis: I_q(t) = E [1/X'_q exp(-t/T'_q) + 1/X_q] (20), bounds (21);
T'_q0 = T'_q X_q / X'_q (17).

The method assumes a sustained terminal short circuit from no load; applied to
short faults of a loaded, grid-connected machine its estimates are biased, which
is exactly the comparison the paper draws (Table 7).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import differential_evolution

from phid_ros.errors import StageError
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import ScenarioData

Array = NDArray[np.float64]
FIT_SECONDS = 3.0  # "from fault initiation to several seconds post-clearing"
DECIMATE = 20  # the envelope is smooth; 50 Hz is plenty for the fit


class BaselineError(StageError):
    """The IEEE 115 baseline cannot run (it needs fault scenarios)."""


@dataclass
class AxisEnvelope:
    e: float
    x_sync: float
    x_prime: float
    t_short: float  # T'_d or T'_q
    t_open: float  # T'_d0 or T'_q0 by (16)/(17)
    cost: float
    at_bound: list[str] = field(default_factory=list)


def _envelope(fit: Any, cost: float, bounds: Any, names: list[str]) -> AxisEnvelope:
    """One axis's envelope from its fitted (E, X, X', T'); T'_0 = T' X / X' by (16)/(17)."""
    e, x_sync, x_prime, t_short = (float(v) for v in fit[:4])
    return AxisEnvelope(e, x_sync, x_prime, t_short, t_short * x_sync / x_prime, cost, _bound_hits(fit, bounds, names))


@dataclass
class BaselineResult:
    d: AxisEnvelope
    q: AxisEnvelope
    scenarios: list[str]
    problems: list[str] = field(default_factory=list)

    def estimates(self) -> dict[str, Estimate]:
        out = {
            "X_d_prime": Estimate(self.d.x_prime),
            "T_d0_prime": Estimate(self.d.t_open),
            "X_q_prime": Estimate(self.q.x_prime),
            "T_q0_prime": Estimate(self.q.t_open),
        }
        for name in self.d.at_bound + self.q.at_bound:
            if name in out:
                out[name].at_bound = True
        return out


def _fit(t: Array, y: Array, w: Array, bounds: list[tuple[float, float]], seed: int) -> tuple[Array, float]:
    def cost(x: Array) -> Array:
        # vectorised over the DE population: x is (4, S)
        e, xs, xp, tc = (np.atleast_1d(v)[:, None] for v in x)
        model = e * (np.exp(-t[None, :] / tc) / xp + 1.0 / xs)
        return np.sum(w[None, :] * (y[None, :] - model) ** 2, axis=1)

    # the paper's global search (section 3.2.2, step 4); the cost is vectorised over the population
    res = differential_evolution(
        cost,
        bounds,
        seed=seed,
        tol=1e-7,
        maxiter=400,
        popsize=10,
        init="latinhypercube",
        vectorized=True,
        updating="deferred",
        polish=False,
    )
    return np.asarray(res.x, dtype=float), float(res.fun)


def _bound_hits(x: Array, bounds: list[tuple[float, float]], names: list[str]) -> list[str]:
    out = []
    for v, (lo, hi), n in zip(x, bounds, names):
        if v - lo < 1e-4 * (hi - lo) or hi - v < 1e-4 * (hi - lo):
            out.append(n)
    return out


def identify(scenarios: Sequence[ScenarioData], x_d_ref: float, x_q_ref: float, seed: int = 0) -> BaselineResult:
    faults = [s for s in scenarios if s.kind == "fault" and s.role == "identify" and s.k_clear is not None]
    if not faults:
        raise BaselineError("the IEEE 115 baseline needs fault scenarios (short circuits); none in the input")
    ts, mags, iqs, ws = [], [], [], []
    v_pf = []
    for s in faults:
        k0 = s.k_event
        k1 = min(s.n, k0 + int(round(FIT_SECONDS / s.dt)))
        sl = slice(k0, k1, DECIMATE)
        ts.append(np.arange(k0, k1, DECIMATE) * s.dt - k0 * s.dt)
        mags.append(np.hypot(s["i_d"][sl], s["i_q"][sl]))
        iqs.append(s["i_q"][sl])
        duration = (s.k_clear - s.k_event) * s.dt  # type: ignore[operator]
        ws.append(np.full(ts[-1].size, duration))  # (19): weight proportional to fault duration
        v_pf.append(float(np.mean(s["v_t"][s.pre_slice()])))
    t = np.concatenate(ts)
    w = np.concatenate(ws)
    w = w / w.mean()
    e_pf = float(np.mean(v_pf))
    bounds_d = [(0.7 * e_pf, 1.3 * e_pf), (0.8 * x_d_ref, 1.2 * x_d_ref), (0.1, 0.6), (0.2, 2.5)]  # (18)
    bounds_q = [(0.7 * e_pf, 1.3 * e_pf), (0.8 * x_q_ref, 1.2 * x_q_ref), (0.7, 1.1), (0.045, 0.15)]  # (21)
    xd_fit, cost_d = _fit(t, np.concatenate(mags), w, bounds_d, seed)
    xq_fit, cost_q = _fit(t, np.concatenate(iqs), w, bounds_q, seed + 1)
    names_d = ["E", "X_d", "X_d_prime", "T_d_prime"]
    names_q = ["E", "X_q", "X_q_prime", "T_q_prime"]
    d = _envelope(xd_fit, cost_d, bounds_d, names_d)  # (16)
    q = _envelope(xq_fit, cost_q, bounds_q, names_q)  # (17)
    # a short-circuit time constant at its bound carries into the open-circuit one
    d.at_bound += ["T_d0_prime"] if "T_d_prime" in d.at_bound else []
    q.at_bound += ["T_q0_prime"] if "T_q_prime" in q.at_bound else []
    problems = [
        f"IEEE 115 {name} at its bound"
        for name in d.at_bound + q.at_bound
        if not name.startswith("T_") or name.endswith("0_prime")
    ]
    return BaselineResult(d, q, [s.name for s in faults], problems)
