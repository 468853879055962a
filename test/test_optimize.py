"""phid_ros.optimize against scipy.optimize itself: the replayed searches bit for bit, the
envelope fit at the least-squares optimum."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import curve_fit, minimize_scalar
from scipy.optimize import differential_evolution as scipy_de

from phid_ros.optimize import bounded_scalar_minimum, decay_fit, differential_evolution


def _envelope_cost(seed: int):
    """The IEEE 115 envelope problem's shape: E (exp(-t/T)/X' + 1/X), weighted, with noise."""
    rng = np.random.default_rng(seed)
    t = np.tile(np.arange(0, 3, 0.02), 3)
    y = 1.1 * (np.exp(-t / 0.8) / 0.3 + 1 / 1.8) * (1 + 0.01 * rng.standard_normal(t.size))
    w = np.repeat([0.5, 1.0, 1.5], t.size // 3)

    def cost(x):
        e, xs, xp, tc = (np.atleast_1d(v)[:, None] for v in x)
        return np.sum(w * (y - e * (np.exp(-t / tc) / xp + 1.0 / xs)) ** 2, axis=1)

    return cost


def _rosenbrock(x):
    return np.sum(100.0 * (x[1:] - x[:-1] ** 2) ** 2 + (1 - x[:-1]) ** 2, axis=0)


@pytest.mark.parametrize(
    "cost, bounds, seed, tol, popsize",
    [
        (_envelope_cost(0), [(0.8, 1.4), (1.4, 2.2), (0.1, 0.6), (0.2, 2.5)], 0, 1e-7, 10),
        (_envelope_cost(1), [(0.8, 1.4), (1.4, 2.2), (0.7, 1.1), (0.045, 0.15)], 1, 1e-7, 10),
        (_rosenbrock, [(-2.0, 2.0)] * 3, 7, 1e-9, 6),
        (_rosenbrock, [(-1.0, 3.0), (0.5, 0.5), (-1.0, 3.0)], 3, 1e-6, 5),  # a parameter fixed by its bounds
    ],
)
def test_differential_evolution_is_scipys_bit_for_bit(cost, bounds, seed, tol, popsize):
    want = scipy_de(
        cost,
        bounds,
        seed=seed,
        tol=tol,
        maxiter=400,
        popsize=popsize,
        init="latinhypercube",
        vectorized=True,
        updating="deferred",
        polish=False,
    )
    x, fun = differential_evolution(cost, bounds, seed=seed, tol=tol, maxiter=400, popsize=popsize)
    assert x.tolist() == want.x.tolist()
    assert fun == float(want.fun)


def test_differential_evolution_stops_at_maxiter_where_scipy_does():
    cost = _envelope_cost(2)
    bounds = [(0.8, 1.4), (1.4, 2.2), (0.1, 0.6), (0.2, 2.5)]
    want = scipy_de(
        cost, bounds, seed=5, tol=1e-12, maxiter=7, popsize=10, vectorized=True, updating="deferred", polish=False
    )
    x, fun = differential_evolution(cost, bounds, seed=5, tol=1e-12, maxiter=7, popsize=10)
    assert x.tolist() == want.x.tolist() and fun == float(want.fun)


@pytest.mark.parametrize(
    "f, a, b, xatol",
    [
        (lambda x: (x - 0.3) ** 2, -1.0, 2.0, 1e-7),
        (lambda x: math.cos(3 * x) + 0.1 * x, -2.0, 2.0, 1e-7),
        (lambda x: math.exp(x) - 2 * x, -3.0, 3.0, 1e-5),
        (lambda x: x, 1.0, 4.0, 1e-7),  # the minimum on a bound
        (lambda x: abs(x - 1.2345), 0.0, 3.0, 1e-9),  # a kink: golden sections only
        (lambda x: 5.0, 0.0, 1.0, 1e-7),  # flat
    ],
)
def test_bounded_scalar_minimum_is_scipys_bit_for_bit(f, a, b, xatol):
    want = minimize_scalar(f, bounds=(a, b), method="bounded", options={"xatol": xatol})
    assert bounded_scalar_minimum(f, a, b, xatol=xatol) == float(want.x)


def test_decay_fit_reaches_the_least_squares_optimum():
    rng = np.random.default_rng(4)
    for _ in range(6):
        t = np.sort(rng.uniform(0, 10, 9))
        t -= t[0]
        y = 2.0 * np.exp(-0.3 * t) * (1 + 0.05 * rng.standard_normal(t.size))

        def env(tt, a0, alpha):
            return a0 * np.exp(-alpha * tt)

        tight, _ = curve_fit(env, t, y, p0=(y[0], 0.5), method="lm", maxfev=50_000, ftol=1e-15, xtol=1e-15, gtol=0)
        got = decay_fit(t, y, float(y[0]), 0.5)
        assert np.allclose(got, tight, rtol=1e-8, atol=0)


def test_decay_fit_on_exact_data_and_its_failure():
    t = np.linspace(0, 4, 9)
    a0, alpha = decay_fit(t, 3.0 * np.exp(-0.7 * t), 1.0, 0.1)
    assert a0 == pytest.approx(3.0, rel=1e-12) and alpha == pytest.approx(0.7, rel=1e-12)
    with pytest.raises(ValueError, match="decay_fit"):
        decay_fit(t, np.full(t.size, np.nan), 1.0, 0.5)
