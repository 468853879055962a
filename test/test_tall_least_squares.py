"""A tall least-squares problem compressed is the full one to the solver (phid_ros.tall_least_squares)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from phid_ros.tall_least_squares import compress, forward_difference_steps, solve


def test_the_compressed_jacobian_keeps_the_gauss_newton_model() -> None:
    rng = np.random.default_rng(7)
    A = rng.normal(size=(20_000, 9)) * np.logspace(0, 4, 9)  # [r, J], columns of very different size
    r, J = A[:, 0], A[:, 1:]
    Jc = compress(A.copy())
    rc = np.zeros(9)
    rc[0] = np.linalg.norm(r)
    assert Jc.shape == (9, 8)
    np.testing.assert_allclose(Jc.T @ Jc, J.T @ J, rtol=1e-11)
    np.testing.assert_allclose(Jc.T @ rc, J.T @ r, rtol=1e-11)
    np.testing.assert_allclose(np.linalg.norm(Jc, axis=0), np.linalg.norm(J, axis=0), rtol=1e-12)


def test_fewer_rows_than_columns_still_give_a_square_factor() -> None:
    A = np.arange(12.0).reshape(3, 4) + np.eye(3, 4)
    Jc = compress(A.copy())
    assert Jc.shape == (4, 3)
    np.testing.assert_allclose(Jc.T @ Jc, A[:, 1:].T @ A[:, 1:], rtol=1e-12)


def test_the_solver_takes_the_same_steps_on_the_compressed_problem() -> None:
    """A bounded exponential fit: scipy's trf on the 4000 rows and on their (k + 1)-row compression."""
    t = np.linspace(0.0, 8.0, 4000)
    y = 1.7 * np.exp(-t / 0.9) + 0.4 * np.exp(-t / 3.1) + 0.01 * np.sin(40 * t)

    def r_of(x: np.ndarray) -> np.ndarray:
        return x[0] * np.exp(-t / x[1]) + x[2] * np.exp(-t / x[3]) - y

    def jac_of(x: np.ndarray) -> np.ndarray:
        e1, e2 = np.exp(-t / x[1]), np.exp(-t / x[3])
        return np.column_stack([e1, x[0] * e1 * t / x[1] ** 2, e2, x[2] * e2 * t / x[3] ** 2])

    x0, bounds = np.array([1.0, 0.5, 1.0, 5.0]), ([0.0, 0.05, 0.0, 0.05], [5.0, 2.5, 5.0, 20.0])
    full = least_squares(r_of, x0, jac=jac_of, bounds=bounds, method="trf", x_scale="jac", max_nfev=12)

    def r_small(x: np.ndarray) -> np.ndarray:
        out = np.zeros(5)
        out[0] = np.linalg.norm(r_of(x))
        return out

    small = least_squares(
        r_small,
        x0,
        jac=lambda x: compress(np.column_stack([r_of(x), jac_of(x)])),
        bounds=bounds,
        method="trf",
        x_scale="jac",
        max_nfev=12,
    )
    assert small.nfev == full.nfev
    np.testing.assert_allclose(small.x, full.x, rtol=1e-8)
    np.testing.assert_allclose(2 * small.cost, r_of(full.x) @ r_of(full.x), rtol=1e-10)


def test_the_steps_are_scipy_s_two_point_steps_turned_back_at_a_bound() -> None:
    from scipy.optimize._numdiff import approx_derivative

    t = np.linspace(0.0, 3.0, 50)

    def f(x: np.ndarray) -> np.ndarray:
        return x[0] * np.exp(-t * x[1]) + x[2] * t + np.sin(x[3] * t)

    lo, hi = np.array([-1.0, 0.0, -2.0, 0.5]), np.array([1.0, 4.0, 2.0, 0.5 + 1e-9])
    # inside, on the upper bound (turned back), at a negative value, and a range narrower than the step
    x = np.array([0.3, 4.0, -1.5, 0.5])
    h = forward_difference_steps(x, lo, hi)
    assert h[1] < 0 and h[2] < 0 and 0 < h[3] <= 1e-9
    ours = np.column_stack([(f(x + np.eye(4)[i] * h[i]) - f(x)) / h[i] for i in range(4)])
    theirs = approx_derivative(f, x, method="2-point", bounds=(lo, hi))
    np.testing.assert_array_equal(ours, theirs)  # bit for bit: scipy's own differences


def test_solve_is_scipy_s_least_squares_on_the_full_rows() -> None:
    """The same bounded fit by scipy on its 4000 rows (its own differences) and through the
    compression: the same evaluations, the same solution, and the full residual and Jacobian."""
    from scipy.optimize import least_squares

    t = np.linspace(0.0, 8.0, 4000)
    y = 1.7 * np.exp(-t / 0.9) + 0.4 * np.exp(-t / 3.1) + 0.01 * np.sin(40 * t)

    def r_of(x: np.ndarray) -> np.ndarray:
        return x[0] * np.exp(-t / x[1]) + x[2] * np.exp(-t / x[3]) - y

    x0, lo, hi = np.array([1.0, 0.5, 1.0, 5.0]), np.array([0.0, 0.05, 0.0, 0.05]), np.array([5.0, 2.5, 5.0, 20.0])
    full = least_squares(r_of, x0, bounds=(lo, hi), x_scale="jac", max_nfev=30)
    ours = solve(r_of, x0, lo, hi, max_nfev=30)
    assert ours.nfev == full.nfev and ours.status == full.status
    np.testing.assert_allclose(ours.x, full.x, rtol=1e-7)
    assert ours.cost == pytest.approx(full.cost, rel=1e-9)
    np.testing.assert_array_equal(ours.fun, r_of(ours.x))
    assert ours.jac.shape == (4000, 4)
    np.testing.assert_allclose(ours.jac, full.jac, rtol=1e-4, atol=1e-6)
    # a start on a bound: scipy's differences there step inward, and so do ours
    on_bound = np.array([5.0, 0.5, 1.0, 5.0])
    a = least_squares(r_of, on_bound, bounds=(lo, hi), x_scale="jac", max_nfev=30)
    b = solve(r_of, on_bound, lo, hi, max_nfev=30)
    assert b.nfev == a.nfev
    np.testing.assert_allclose(b.x, a.x, rtol=1e-7)
