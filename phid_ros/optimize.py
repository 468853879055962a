"""The searches the default identification runs, on numpy alone.

Why not ``scipy.optimize``: importing it costs 0.45-0.55 s per process on the 2-core reference
machine (it pulls in scipy.linalg, scipy.fft, scipy.special and the array-API shim, which walks
numpy's namespace into numpy.f2py and numpy.testing). That is more than the whole warm
identification of a recording, and a fresh ``phid identify``, every replay and every
recalibration process paid it. The default identification used three things from it:

- :func:`bounded_scalar_minimum`: ``minimize_scalar(method="bounded")`` (Brent's fminbound, the
  1-D searches of stage 3's variable projection);
- :func:`differential_evolution`: ``differential_evolution`` as the IEEE 115 baseline calls it
  (latin hypercube start, best1bin, dithered mutation, deferred updating, a vectorised cost, no
  polish), the paper's method (section 3.2);
- :func:`decay_fit`: ``curve_fit(method="lm")`` of stage 1's speed envelope (the differential
  damping method, on dampingless simulations).

The first two follow scipy 1.17's code statement by statement, the random draws in the same order
from the same legacy ``RandomState`` an integer seed makes there, so their results are bit for bit
scipy's; tests hold them to scipy itself. A side effect a plant engineer can use: the baseline's
figures no longer move when scipy is upgraded. The third is not MINPACK replayed: it reaches the
same least-squares optimum, tighter (see its docstring). What the defaults do not run (the
paper's global stage 3, stage 2's L-BFGS-B) still imports scipy, when used.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

_SQRT_EPS = math.sqrt(2.2e-16)  # scipy's constant, not the machine's epsilon: the same stopping point
_GOLDEN = 0.5 * (3.0 - math.sqrt(5.0))


def bounded_scalar_minimum(f: Callable[[float], float], a: float, b: float, xatol: float = 1e-5) -> float:
    """The minimiser of ``f`` on ``[a, b]``: golden sections and parabolic steps (fminbound).

    scipy's ``_minimize_scalar_bounded`` with ``maxiter=500``; returns its ``x``.
    """
    if not (math.isfinite(a) and math.isfinite(b)) or a > b:
        raise ValueError(f"bounded_scalar_minimum: bounds ({a}, {b}) must be finite and ordered")
    fulc = a + _GOLDEN * (b - a)
    nfc = xf = fulc
    rat = e = 0.0
    fx = f(xf)
    num = 1
    ffulc = fnfc = fx
    xm = 0.5 * (a + b)
    tol1 = _SQRT_EPS * abs(xf) + xatol / 3.0
    tol2 = 2.0 * tol1
    while abs(xf - xm) > (tol2 - 0.5 * (b - a)):
        golden = True
        if abs(e) > tol1:  # try a parabola through the three best points
            golden = False
            r = (xf - nfc) * (fx - ffulc)
            q = (xf - fulc) * (fx - fnfc)
            p = (xf - fulc) * q - (xf - nfc) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            r = e
            e = rat
            if abs(p) < abs(0.5 * q * r) and p > q * (a - xf) and p < q * (b - xf):
                rat = (p + 0.0) / q
                x = xf + rat
                if (x - a) < tol2 or (b - x) < tol2:
                    rat = tol1 * (_sign(xm - xf) + float(xm - xf == 0))
            else:
                golden = True
        if golden:
            e = (a - xf) if xf >= xm else (b - xf)
            rat = _GOLDEN * e
        x = xf + (_sign(rat) + float(rat == 0)) * max(abs(rat), tol1)
        fu = f(x)
        num += 1
        if fu <= fx:
            if x >= xf:
                a = xf
            else:
                b = xf
            fulc, ffulc = nfc, fnfc
            nfc, fnfc = xf, fx
            xf, fx = x, fu
        else:
            if x < xf:
                a = x
            else:
                b = x
            if fu <= fnfc or nfc == xf:
                fulc, ffulc = nfc, fnfc
                nfc, fnfc = x, fu
            elif fu <= ffulc or fulc == xf or fulc == nfc:
                fulc, ffulc = x, fu
        xm = 0.5 * (a + b)
        tol1 = _SQRT_EPS * abs(xf) + xatol / 3.0
        tol2 = 2.0 * tol1
        if num >= 500:
            break
    return float(xf)


def _sign(v: float) -> float:
    """np.sign of a float (NaN stays NaN: a NaN objective must not become a step of 0)."""
    return math.copysign(1.0, v) if v != 0 else (v if v != v else 0.0)


def differential_evolution(
    cost: Callable[[Array], Array],
    bounds: Sequence[tuple[float, float]],
    *,
    seed: int,
    tol: float,
    maxiter: int,
    popsize: int,
) -> tuple[Array, float]:
    """(x, cost(x)) of the best member: best1bin with mutation dithered in [0.5, 1), crossover 0.7.

    ``cost`` takes the population as columns, (parameters, members), and returns (members,).
    Stops when the spread of the population's costs is within ``tol`` of their mean.
    """
    rng = np.random.RandomState(seed)  # what scipy's check_random_state makes of an integer seed
    limits = np.array(bounds, dtype=float).T
    if limits.shape[0] != 2 or not np.all(np.isfinite(limits)):
        raise ValueError("differential_evolution: bounds must be finite (min, max) pairs")
    centre = 0.5 * (limits[0] + limits[1])
    span = np.fabs(limits[0] - limits[1])
    n_par = limits.shape[1]
    fixed = int(np.count_nonzero(limits[0] == limits[1]))
    members = max(5, popsize * max(1, n_par - fixed))

    def energies(unit: Array) -> Array:
        return np.squeeze(np.atleast_1d(cost((centre + (unit - 0.5) * span).T)))

    # latin hypercube start: one sample per stratum of [0, 1) for every parameter, strata shuffled
    strata = (1.0 / members) * rng.uniform(size=(members, n_par)) + np.linspace(0.0, 1.0, members, endpoint=False)[
        :, None
    ]
    population = np.zeros_like(strata)
    for j in range(n_par):
        population[:, j] = strata[rng.permutation(range(members)), j]
    energy = energies(population)
    _promote_lowest(population, energy)

    index = np.arange(members)  # shuffled in place member after member, as scipy's _select_samples
    rows = np.arange(members)
    shuffle = rng.shuffle
    r0, r1 = [0] * members, [0] * members
    for _ in range(maxiter):
        scale = rng.uniform(0.5, 1.0)
        for c in range(members):
            shuffle(index)
            # scipy keeps the first of index[:6] that are not c; best1 uses two of them
            a, b, d = index[:3].tolist()
            r0[c], r1[c] = (b, d) if a == c else ((a, d) if b == c else (a, b))
        mutant = population[0] + scale * (population[r0] - population[r1])
        fill = rng.randint(n_par, size=members, dtype="int64")
        cross = rng.uniform(size=(members, n_par)) < 0.7
        cross[rows, fill] = True
        trial = np.where(cross, mutant, population)
        outside = (trial > 1) | (trial < 0)
        if n_out := np.count_nonzero(outside):
            trial[outside] = rng.uniform(size=n_out)
        trial_energy = energies(trial)
        better = trial_energy <= energy
        population = np.where(better[:, None], trial, population)
        energy = np.where(better, trial_energy, energy)
        _promote_lowest(population, energy)
        if np.std(energy) <= tol * np.abs(np.mean(energy)):
            break
    return centre + (population[0] - 0.5) * span, float(energy[0])


def _promote_lowest(population: Array, energy: Array) -> None:
    """The lowest cost into row 0 (a swap, as scipy: the order of the others matters to the draws)."""
    best = int(np.argmin(energy))
    energy[[0, best]] = energy[[best, 0]]
    population[[0, best], :] = population[[best, 0], :]


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
