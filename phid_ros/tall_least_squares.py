"""Least squares on tall residuals: the solver sees the problem compressed to k + 1 rows.

A play-in's residual has a row per channel per sample of every case (tens to hundreds of
thousands) and a handful of columns. scipy's trust-region reflective solver takes an SVD of the
whole Jacobian and forms J'r and J'J from it at every step; on the exciter search of a
commissioning day that was 82 s of SVDs and 43 s of products in 184 s. [r, J] = Q R gives a
(k + 1)-row pair (||r|| e_1, R[:, 1:]) with the same sum of squares, J'r and J'J, so the same
Gauss-Newton model, gradient, column scales (``x_scale="jac"``) and trust-region steps: what the
solver decides on it is what it would decide on the full rows, to rounding.

- :func:`compress`: the compressed Jacobian of a column-major [r, J].
- :func:`forward_difference_steps`: scipy's two-point steps, turned back at a bound.
- :func:`solve`: ``scipy.optimize.least_squares`` (trf) on a residual function through the
  compression, returning the full residual and Jacobian at the solution for the covariances.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
# scipy's relative step for its "2-point" Jacobian (sqrt of the machine epsilon): the steps,
# and so the fits, of the solver's own differences
RELATIVE_STEP = float(np.finfo(float).eps) ** 0.5


def compress(A: Array) -> Array:
    """The Jacobian J~ ((k + 1) x k) that, with the residual ||r|| e_1, is the tall [r, J] ``A`` to the solver.

    ``A`` is overwritten (column-major, it is factorised where it lies).

    R of the QR factorisation [r, J] = Q R (its first row's sign chosen so R[0, 0] = ||r||) gives
    J~ = R[:, 1:], and Q'[r, J] = R: the pair (||r|| e_1, J~) has the sum of squares, J'r and J'J of
    (r, J), and so the same Gauss-Newton model, gradient, column scales and covariance. scipy's
    trust-region solver takes an SVD of its Jacobian at every step; on the play-in's rows (six
    channels at every 2 ms of every window) that SVD cost as much as the play-ins themselves
    (38 s of 129 s of phid diagnose bags/saturation, one worker).
    """
    from scipy.linalg.lapack import dgeqrf

    m, n = A.shape
    R = np.zeros((n, n))
    # LAPACK's Householder QR in place on the column-major A (numpy's qr copied it and took 2.7x
    # as long: 20 against 7.3 ms on 126 000 x 15); R is the upper triangle of what it returns
    qr, _, _, info = dgeqrf(A, overwrite_a=True)
    if info != 0:
        raise ValueError(f"QR of the Jacobian failed (LAPACK info {info})")
    top = np.triu(qr[: min(m, n)])
    R[: top.shape[0]] = top
    if R[0, 0] < 0:
        R[0] = -R[0]
    return R[:, 1:]


def square_sum(r: Array) -> float:
    """The sum of squares the solver takes, inf where a residual or the sum is not finite."""
    with np.errstate(over="ignore", invalid="ignore"):
        total = float(r @ r)
    return total if np.all(np.isfinite(r)) and math.isfinite(total) else math.inf


def forward_difference_steps(x: Array, lo: Array, hi: Array) -> Array:
    """scipy's two-point steps at ``x`` (sqrt(eps) x max(1, |x|), signed as x), each turned back where
    it would leave the bounds and the other side has room, else the room there is (its rule for a
    one-sided difference in bounds); each step is what x + h - x is in floating point."""
    sign = np.where(x >= 0, 1.0, -1.0)
    h = RELATIVE_STEP * sign * np.maximum(1.0, np.abs(x))
    below, above = x - lo, hi - x
    outside = (x + h < lo) | (x + h > hi)
    fits = np.abs(h) <= np.maximum(below, above)
    h = np.where(outside & fits, -h, h)
    h = np.where(~fits & (above >= below), above, h)
    h = np.where(~fits & (above < below), -below, h)
    return (x + h) - x


@dataclass(frozen=True)
class Solution:
    """What the caller reads of scipy's result, with the full residual and Jacobian at ``x``."""

    x: Array
    cost: float  # half the sum of squares, as scipy's
    fun: Array  # the full residual at x
    jac: Array  # the full Jacobian at x (forward differences)
    nfev: int
    status: int
    message: str


def solve(residual: Callable[[Array], Array], x0: Array, lo: Array, hi: Array, max_nfev: int) -> Solution:
    """``least_squares(residual, x0, bounds=(lo, hi), x_scale="jac", max_nfev=max_nfev)``, its
    Jacobian scipy's two-point differences, solved through :func:`compress`.

    The residual is evaluated once per point: the solver asks for it and then for the Jacobian
    at the same x, which reuses it; the last full pair is kept for :class:`Solution`.
    """
    from scipy.optimize import least_squares

    x0 = np.asarray(x0, dtype=float)
    residuals: dict[bytes, Array] = {}
    full: dict[bytes, tuple[Array, Array]] = {}

    def at(x: Array) -> Array:
        key = x.tobytes()
        if key not in residuals:
            if len(residuals) > 4:  # the solver only returns to its current point
                residuals.clear()
            residuals[key] = np.asarray(residual(x), dtype=float)
        return residuals[key]

    def jacobian(x: Array) -> tuple[Array, Array]:
        key = x.tobytes()
        if key not in full:
            r = at(x)
            steps = forward_difference_steps(x, lo, hi)
            J = np.empty((r.size, x.size), order="F")
            for i, h in enumerate(steps):
                shifted = x.copy()
                shifted[i] += h
                J[:, i] = (np.asarray(residual(shifted), dtype=float) - r) / h
            full.clear()
            full[key] = r, J
        return full[key]

    def compressed_residual(x: Array) -> Array:
        out = np.zeros(x.size + 1)
        out[0] = math.sqrt(square_sum(at(x)))  # inf where the residual is not finite, as scipy's check wants
        return out

    def compressed_jacobian(x: Array) -> Array:
        r, J = jacobian(x)
        A = np.empty((r.size, x.size + 1), order="F")
        A[:, 0], A[:, 1:] = r, J
        return compress(A)

    sol = least_squares(
        compressed_residual, x0, jac=compressed_jacobian, bounds=(lo, hi), x_scale="jac", max_nfev=max_nfev
    )
    r, J = jacobian(np.asarray(sol.x, dtype=float))
    return Solution(np.asarray(sol.x, float), float(sol.cost), r, J, int(sol.nfev), int(sol.status), str(sol.message))
