"""Stage 1's envelope fit: our own Levenberg-Marquardt for one decaying exponential.

Stage 1's differential damping method fits ``A0 exp(-alpha t)`` to the peaks of the speed
oscillation (the paper's (23)-(24)). ``scipy.optimize.curve_fit(method="lm")`` stops at MINPACK's
default tolerance (ftol 1.5e-8), 1e-7-1e-6 short of the least-squares optimum on these nine-point
envelopes; :func:`decay_fit` runs the exact two-column Jacobian to a relative step of 1e-13 and
raises instead of returning its start. ``benchmarks/bench_own_code.py`` measures it against
curve_fit. Every other search the identification runs is scipy.optimize's, called where it runs.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def decay_fit(t: Array, y: Array, a0: float, alpha: float, max_steps: int = 200) -> tuple[float, float]:
    """Least-squares ``(a0, alpha)`` of ``y = a0 exp(-alpha t)`` from a start: Levenberg-Marquardt.

    Stage 1's envelope fit, ``curve_fit(method="lm")`` before. It is not a replay of MINPACK: it
    reaches the same least-squares optimum with the exact Jacobian and runs on to a relative
    step of 1e-13, where MINPACK stopped at 1.5e-8, so results agree to about 1e-8 (far inside
    the digits stage 1 prints). Raises ValueError when no step lowers the squares from the start.
    """
    x = np.array([a0, alpha], dtype=float)
    r = y - x[0] * np.exp(-x[1] * t)
    sse = float(r @ r)
    if not math.isfinite(sse):
        raise ValueError(f"decay_fit: the squares are not finite at the start ({sse})")
    damping = 1e-3
    for _ in range(max_steps):
        decay = np.exp(-x[1] * t)
        jac = np.column_stack([decay, -x[0] * t * decay])  # d model / d (a0, alpha)
        normal = jac.T @ jac
        grad = jac.T @ r
        while True:
            try:
                step = np.linalg.solve(normal + damping * np.diag(np.diag(normal)), grad)
            except np.linalg.LinAlgError:
                step = np.full(2, np.nan)
            trial = x + step
            r_trial = y - trial[0] * np.exp(-trial[1] * t)
            sse_trial = float(r_trial @ r_trial)
            if sse_trial <= sse:
                break
            damping *= 10.0
            if damping > 1e16:  # no step lowers the squares: x is the optimum to rounding
                return _finite_pair(x)
        damping = max(damping / 10.0, 1e-15)
        x, r, sse = trial, r_trial, sse_trial
        if np.all(np.abs(step) <= 1e-13 * (np.abs(x) + 1e-300)):
            return _finite_pair(x)
    raise ValueError(f"decay_fit: no convergence in {max_steps} steps (a0 = {x[0]:.6g}, alpha = {x[1]:.6g})")


def _finite_pair(x: Array) -> tuple[float, float]:
    if not np.all(np.isfinite(x)):
        raise ValueError("decay_fit: the fit left the finite numbers")
    return float(x[0]), float(x[1])
