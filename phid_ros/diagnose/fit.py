"""Output-error fit of an extended model: base parameters and effect parameters together.

The residual is every output channel (omega, delta, I_d, I_q, P_e, Q_e) of the
play-in against the measurement, at every play-in step, each divided by its
sensor-noise standard deviation (so the channels weigh as the data deserve and
the sum of squares is a chi-square). The base parameters always float: an effect
is only judged against a base model that was refitted alongside it, or the
base's compensation for the missing effect would count against the effect.

Jacobians are forward differences computed in *one* vectorised play-in (one
model column per parameter); trust-region reflective least squares keeps every
parameter in its bounds (log scale for positive ones).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from phid_ros import jit
from phid_ros.diagnose.candidates import Candidate, FreeParameter
from phid_ros.errors import PhidError
from phid_ros.ident.plant_playin import PlayIn, play_in, residual_matrix
from phid_ros.ident.scenario import ScenarioData
from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ
from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME
from phid_ros.tall_least_squares import compress
from phid_ros.tall_least_squares import square_sum as _square_sum

Array = NDArray[np.float64]
FD_STEP = 1e-5  # relative (log-scale) finite-difference step; the play-in is deterministic
SCREEN_CHUNK = 12  # models per play-in run when only their chi-square is kept


@dataclass
class ModelSpec:
    """A base model with zero or more effects: values of every parameter (scalars)."""

    base: dict[str, float]
    effects: list[tuple[type[Candidate], dict[str, Any]]] = field(default_factory=list)

    @property
    def names(self) -> list[str]:
        return [c.name() for c, _ in self.effects]

    def effect_values(self) -> dict[str, dict[str, Any]]:
        return {c.name(): dict(v) for c, v in self.effects}

    def plant_effects(self) -> list[tuple[type, dict[str, Any]]]:
        return [(c.effect, v) for c, v in self.effects]


@dataclass
class FitResult:
    model: ModelSpec
    chi2: float  # sum of squared noise-normalised residuals on the fit windows
    n: int  # residual samples
    k: int  # free parameters
    nfev: int = 0
    message: str = ""
    # standard deviation of each free effect parameter (linear units), per effect of the model
    effect_std: list[dict[str, float]] = field(default_factory=list)
    base_std: dict[str, float] = field(default_factory=dict)  # the same for the base parameters
    # the solution in the solver's coordinates, the parameter of each (effect index or -1, and
    # its transform), and the compressed Jacobian there: what a neighbouring fit starts from
    x: Array | None = None
    free: tuple[tuple[int, FreeParameter], ...] = ()
    jac: Array | None = None

    @property
    def bic(self) -> float:
        return self.n * math.log(self.chi2 / self.n) + self.k * math.log(self.n)


def base_free(
    start: Mapping[str, float], wide: Collection[str] = (), held: Collection[str] = ()
) -> list[FreeParameter]:
    """Base parameters free within a factor of 3 of the start (and their physical range).

    ``wide``: parameters whose start carries no information (the identification left them at a
    search bound) are free over their whole physical range. Saturation on GENROU's q axis sent
    stage 3's T'_q0 to its 3 s bound; within a factor of 3 of each previous fit it could not get
    below 0.33 s in the round that named saturation (truth 0.135 s), and the fit stalled there.
    ``held``: parameters kept at their start (not free).
    """
    out = []
    for n in PARAMETER_NAMES:
        if n in held:
            continue
        s = SPECS_BY_NAME[n]
        v = float(start[n])
        if n == "D":  # may be near zero: linear scale
            out.append(FreeParameter(n, 0.0, max(s.high, 3 * v), log=False))
        elif n in wide:
            out.append(FreeParameter(n, s.low, s.high, log=True))
        else:
            out.append(FreeParameter(n, max(s.low, v / 3), min(s.high, 3 * v), log=True))
    return out


def finite(r: Array) -> Array:
    """``r`` with every non-finite value at 1e6, in place: a diverged model is simply a very bad one."""
    if np.isfinite(np.sum(r)):  # one pass and no temporary: a finite sum has only finite terms
        return r
    bad = ~np.isfinite(r)
    r[bad] = 1e6
    return r


def chi_square(
    windows: Sequence[ScenarioData],
    sigma: Mapping[str, float],
    base: Mapping[str, Any],
    effects: Sequence[tuple[type, Mapping[str, Any]]],
    m: int,
    f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ,
) -> Array:
    """Chi-square of each of ``m`` models (parameters as in :func:`play_in`), in chunks of models.

    A screening grid of hundreds of models in one run held every trajectory at once (1.2 GB
    for the saturation grid); chunks keep the memory flat. Compiled, a play-in costs per
    column, so small chunks cost no speed: 12 models took a worker's peak from 616 to 414 MB
    in phid diagnose bags/saturation (48 were chosen for the numpy play-in, whose time is per step).
    """
    out = np.empty(m)
    for a in range(0, m, SCREEN_CHUNK):
        sl = slice(a, min(a + SCREEN_CHUNK, m))
        k = sl.stop - sl.start
        r = residual_matrix(
            windows,
            {n: _columns(v, sl, m) for n, v in base.items()},
            [(cls, {n: _columns(v, sl, m) for n, v in values.items()}) for cls, values in effects],
            k,
            sigma,
            f_nominal_hz=f_nominal_hz,
        )
        with np.errstate(over="ignore"):  # a model that diverged to 1e200 squares to inf: the worst, as it is
            out[sl] = np.sum(finite(r) ** 2, axis=0)
    return out


def _columns(v: Any, sl: slice, m: int) -> Any:
    a = np.asarray(v)
    return a[sl] if a.ndim == 1 and len(a) == m and a.dtype.kind in "fi" else v


class Problem:
    """The least-squares problem of one model structure on a set of windows."""

    def __init__(
        self,
        windows: Sequence[ScenarioData],
        sigma: Mapping[str, float],
        spec: ModelSpec,
        f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ,
        basin: bool = False,
        wide: Collection[str] = (),
        held: Collection[str] = (),
    ) -> None:
        """``basin``: the last effect's searched parameters are free too (see ``basin_free``);
        ``wide``, ``held``: base parameters free over their physical range, and not free
        (see :func:`base_free`)."""
        self.windows, self.sigma, self.spec, self.f = list(windows), dict(sigma), spec, f_nominal_hz
        self.free: list[tuple[int, FreeParameter]] = [(-1, p) for p in base_free(spec.base, wide, held)]
        for i, (cand, _) in enumerate(spec.effects):
            self.free.extend((i, p) for p in cand.free())
        if basin and spec.effects:
            self.free.extend((len(spec.effects) - 1, p) for p in spec.effects[-1][0].basin_free())
        self.nfev = 0

    def x0(self) -> Array:
        x = [p.to_x(self._value(i, p.name)) for i, p in self.free]
        return self.inside(np.array(x, float))

    def inside(self, x: Array) -> Array:
        lo, hi = self.bounds()
        return np.clip(x, lo + 1e-9, hi - 1e-9)

    def bounds(self) -> tuple[Array, Array]:
        b = np.array([p.x_bounds for _, p in self.free])
        return b[:, 0], b[:, 1]

    def _value(self, i: int, name: str) -> Any:
        return self.spec.base[name] if i < 0 else self.spec.effects[i][1][name]

    def columns(self, X: Array) -> tuple[dict[str, Any], list[tuple[type, dict[str, Any]]]]:
        """Parameter values for the models whose x vectors are the columns of ``X``."""
        base: dict[str, Any] = dict(self.spec.base)
        effects = [(c.effect, dict(v)) for c, v in self.spec.effects]
        for row, (i, p) in enumerate(self.free):
            v = p.from_x(X[row])
            if i < 0:
                base[p.name] = v
            else:
                effects[i][1][p.name] = v
        return base, effects

    def residual_matrix(self, X: Array, out: Array | None = None, order: str = "C") -> Array:
        """``finite(residuals(play_in(...), sigma, out))`` of the models ``X`` (one per column),
        without keeping their trajectories; a new ``out`` is laid out in ``order``."""
        base, effects = self.columns(X)
        self.nfev += X.shape[1]
        return finite(residual_matrix(self.windows, base, effects, X.shape[1], self.sigma, out, self.f, order=order))

    def spec_at(self, x: Array) -> ModelSpec:
        base, effects = self.columns(x[:, None])
        return ModelSpec(
            {k: float(np.ravel(v)[0]) for k, v in base.items()},
            [
                (cand, {k: (float(np.ravel(v)[0]) if np.asarray(v).dtype.kind == "f" else v) for k, v in vals.items()})
                for (cand, _), (_, vals) in zip(self.spec.effects, effects)
            ],
        )


def fit(problem: Problem, max_nfev: int = 12, x0: Array | None = None) -> FitResult:
    """Local least squares from the problem's start values (or from ``x0``, kept inside the bounds).

    Compiled (phid_ros.sim.kernel), a play-in costs per column, so a point is simulated
    alone and its finite-difference columns only when the solver asks for the Jacobian
    (it does not at the points it rejects). In numpy a run of one model costs nearly what
    a run of a dozen does (the time is per step, not per column), so there every point is
    simulated together with its columns in one run.

    The solver sees the problem compressed (:func:`compress`): a (k + 1)-row residual and
    Jacobian with the same sum of squares, gradient and J'J as the play-in's hundreds of
    thousands of rows, so every step it takes is the step it would take on the full rows.
    """
    lo, hi = problem.bounds()
    together = not jit.available()
    cache: dict[bytes, tuple[Array, Array | None]] = {}

    def evaluate(x: Array, want_jac: bool) -> tuple[Array, Array | None]:
        """The residual at ``x`` and, if asked, the compressed Jacobian there."""
        key = x.tobytes()
        r, J = cache.get(key, (None, None))
        if r is not None and (J is not None or not want_jac):
            return r, J
        steps = FD_STEP * np.maximum(1.0, np.abs(x))
        steps = np.where(x + steps > hi, -steps, steps)  # stay inside the bounds
        if r is None and not (want_jac or together):
            r = problem.residual_matrix(x[:, None])[:, 0]
        else:
            # column-major: each column contiguous for the differences and LAPACK's QR, no copy
            if r is None:  # r and the shifted columns in one run: [r, r(x + h_1 e_1), ...]
                X = np.hstack([x[:, None], x[:, None] + np.diag(steps)])
                A = problem.residual_matrix(X, order="F")
            else:
                A = np.empty((len(r), len(x) + 1), order="F")
                A[:, 0] = r
                problem.residual_matrix(x[:, None] + np.diag(steps), out=A[:, 1:])
            r = A[:, 0].copy()
            A[:, 1:] -= A[:, :1]
            A[:, 1:] /= steps[None, :]  # A = [r, J] in place: no second tall array
            J = compress(A)
        cache.clear()
        cache[key] = r, J
        return r, J

    def residual(x: Array) -> Array:
        r = evaluate(x, False)[0]
        out = np.zeros(len(x) + 1)
        out[0] = math.sqrt(_square_sum(r))  # inf where the play-in diverged, without a warning
        return out

    x0 = chosen_start(lambda x: evaluate(x, False)[0], None if x0 is None else problem.inside(x0), problem.x0())
    sol = least_squares(
        residual,
        x0,
        jac=lambda x: evaluate(x, True)[1],
        bounds=(lo, hi),
        method="trf",
        x_scale="jac",
        max_nfev=max_nfev,
    )
    r = evaluate(sol.x, False)[0]
    k = len(x0) + sum(len(c.searched()) for c, _ in problem.spec.effects)
    spec = problem.spec_at(sol.x)
    base_std, effect_std = _std(problem, sol.x, np.asarray(sol.jac), r, k, spec)
    jac = np.asarray(sol.jac)
    return FitResult(
        spec, float(r @ r), len(r), k, sol.nfev, sol.message, effect_std, base_std, sol.x, tuple(problem.free), jac
    )


class FitError(PhidError):
    """A fit cannot start: the play-in diverges at every start tried."""


START_BACKOFFS = 8  # halvings of a predicted start's step back toward the problem's own start


def finite_start(residual: Callable[[Array], Array], start: Array, fallback: Array) -> Array:
    """``start``, or the first point on the way back to ``fallback`` (halving the distance) whose
    residuals are finite.

    Why: a profile point's start is predicted to first order from the final fit's Jacobian; on a
    salient-pole machine with saturation and dampers that prediction took the play-in where it
    diverged, and scipy's solver stopped the whole diagnosis with "Residuals are not finite in
    the initial point". A start the data reject is a start to move, not a crash. Finite means
    the sum of squares the solver takes is finite: on STEPS's saturated GENSAL a diverging
    play-in returned residuals of 1e160 and more, each finite, their square sum not.
    """

    def usable(x: Array) -> bool:
        return math.isfinite(_square_sum(residual(x)))

    x = np.asarray(start, dtype=float)
    for _ in range(START_BACKOFFS + 1):
        if usable(x):
            return x
        x = 0.5 * (x + fallback)
    if usable(fallback):
        return np.asarray(fallback, dtype=float)
    raise FitError("the play-in diverges at the start and on the way back to the model's own values")


def chosen_start(residual: Callable[[Array], Array], predicted: Array | None, own: Array) -> Array:
    """Where a fit starts: ``predicted`` (moved back until finite, :func:`finite_start`) where the
    data like it at least as well as the problem's ``own`` values, else ``own``.

    Why: a profile point's start is predicted to first order from the final fit's Jacobian. On
    STEPS's saturated GENSAL with V_t played in smoothed, holding H 10 % up moved X'_q, T'_q0 and
    the saturation far along nearly flat directions (the Jacobian's smallest singular value 1e-6
    of its largest); the refit from there ended where the held-out play-in diverged, and H, within
    0.03 % of the machine's, was reported not determined. From the final values it refits cleanly.
    """
    if predicted is None:
        return finite_start(residual, own, own)
    x = finite_start(residual, predicted, own)
    return x if _square_sum(residual(x)) <= _square_sum(residual(own)) else np.asarray(own, dtype=float)


def _std(
    problem: Problem, x: Array, J: Array, r: Array, k: int, spec: ModelSpec
) -> tuple[dict[str, float], list[dict[str, float]]]:
    """Standard deviations of the base and effect parameters from the Jacobian at the solution.

    The covariance (J'J)^-1 s^2 takes s^2 from the residual itself (model error counts as noise),
    widened by (1 + rho)/(1 - rho) for the residual's lag-one correlation rho: the play-in's
    residual is smooth in time (the model's error and the 2 ms step), and independent samples
    would make every interval several times too narrow.
    """
    dof = max(len(r) - k, 1)
    s2 = float(r @ r) / dof
    rho = float(np.dot(r[1:], r[:-1]) / max(float(r @ r), 1e-300))
    widen = (1 + rho) / (1 - rho) if 0 < rho < 1 else 1.0
    cov = np.linalg.pinv(J.T @ J) * s2 * widen
    sd_x = np.sqrt(np.maximum(np.diag(cov), 0.0))
    base: dict[str, float] = {}
    effects: list[dict[str, float]] = [{} for _ in spec.effects]
    for row, (i, p) in enumerate(problem.free):
        v = float(np.ravel(p.from_x(x[row]))[0])
        (base if i < 0 else effects[i])[p.name] = float(abs(v) * sd_x[row]) if p.log else float(sd_x[row])
    return base, effects


def evaluate(
    windows: Sequence[ScenarioData],
    sigma: Mapping[str, float],
    spec: ModelSpec,
    f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ,
) -> list[PlayIn]:
    return play_in(windows, spec.base, spec.plant_effects(), f_nominal_hz=f_nominal_hz)
