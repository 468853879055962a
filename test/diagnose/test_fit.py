"""The output-error fit's compressed least-squares problem is the full one to the solver."""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from phid_ros.diagnose.fit import compress


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
