"""One control model fitted to one kind's cases: its constants in their ranges, their stds,
whether the data determine each, and its error on the held-out cases."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros import tall_least_squares
from phid_ros.controls.cases import ControlCase, rmse
from phid_ros.controls.models import ControlModel, ControlParameter, LimitsError
from phid_ros.controls.play import REFERENCE_SEARCH, limited_output, open_limits, simulate_cases, simulate_references
from phid_ros.ident.uncertainty import block_ids, cluster_robust_cov

Array = NDArray[np.float64]

MAX_EVALUATIONS = 200


SECOND_START = 0.15  # the second fit starts this share of each constant's range away from the first's end


# the refits of the profile check start at the optimum, one constant moved: a few steps settle them
PROFILE_EVALUATIONS = 12


EQUAL_FIT = 0.01  # two fits whose rms errors differ by less than this share explain the data equally


DETERMINED_STD = 0.10  # relative std at most, for a fitted parameter to be given as determined


OUTSIDE_LIMITS = 10.0  # a fit's residual where its limits cannot hold an operating point: x the output's range

Limits = dict[str, tuple[float, float, float]]  # limit -> (start, low, high), for a fit that frees it


@dataclass
class ControlFit:
    """A control model fitted to one kind's scenarios."""

    model: str
    kind: str
    parameters: dict[str, float | None]
    uncertainty: dict[str, float | None]
    identifiable: dict[str, bool]
    fit_rmse: float
    heldout_rmse: float | None
    none_heldout_rmse: float | None
    named: bool
    why: str
    references: dict[str, float] = field(default_factory=dict)
    alternatives: dict[str, float] = field(default_factory=dict)  # models that fit as well: their errors
    limits: Limits = field(default_factory=dict)  # the limits this fit freed (reached in the recordings)
    # an output limit not reached: the least it can be, in its own terms (the recordings went that far)
    seen: dict[str, float] = field(default_factory=dict)
    # the limits the fit pressed on an end of their range: it wants them where the recordings say
    # they cannot be (a constant ceiling asked to be both a no-load step's top and a loaded one's)
    pressed: list[str] = field(default_factory=list)

    def as_json(self) -> dict[str, Any]:
        """``model`` is null where none is named; ``fitted_model`` is the best candidate either way."""
        return {
            "model": self.model if self.named else None,
            "fitted_model": self.model,
            "parameters": self.parameters,
            "uncertainty": self.uncertainty,
            "identifiable": self.identifiable,
            "fit_rmse_pu": self.fit_rmse,
            "heldout_rmse_pu": self.heldout_rmse,
            "no_control_heldout_rmse_pu": self.none_heldout_rmse,
            "named": self.named,
            "why": self.why,
            "reference_steps": self.references,
            "fit_as_well": self.alternatives,
            "limits_reached": sorted(self.limits),  # fitted from the recordings' flat tops
            "limits_seen": self.seen,  # a limit not reached is at least this (the recordings went that far)
            "limits_pressed": sorted(self.pressed),  # pressed on an end of its range: flagged, and said
        }


def fit_model(
    model: ControlModel,
    fit: Sequence[ControlCase],
    held: Sequence[ControlCase],
    earlier: Mapping[str, Mapping[str, float]] | None = None,
    *,
    checked: bool = True,
    start_at: Mapping[str, float] | None = None,
    limits: Limits | None = None,
    held_limits: Mapping[str, float] | None = None,
    played_through_limits: bool = False,
) -> ControlFit:
    """``model``'s fitted parameters (log scale, in their ranges; the limits held), their stds
    from the Jacobian, and its error on the held-out cases; started where ``model.start`` says
    from the ``earlier`` models' fits. ``checked``: a constant is given as determined only after
    a second start and a profile agree (the named model's fit); unchecked fits only compete.
    ``limits``: the output limits the recordings reached (:func:`reached_limits`), fitted too,
    the cases played through them (:meth:`ControlModel.limited`), each stepped case's reference
    a constant of the fit. ``held_limits``: limits found by such a fit, held at their values while
    the small-signal constants are fitted and checked on the small-signal tests alone.
    ``played_through_limits``: the cases played through :meth:`ControlModel.limited` whatever
    limits are fitted (a stabiliser fitted through an exciter that reached its own)."""
    problem = _FitProblem(model, fit, dict(limits or {}), dict(held_limits or {}), played_through_limits)
    sol = problem.solve(problem.start(earlier, start_at))
    # a second opinion from a start moved away in every constant (alternate signs): where both
    # fits explain the data equally well but a constant differs, the data do not determine it,
    # whatever the Jacobian at either says (ESST5B's T_B2 came out 0.019 +- 0.0015 from one
    # start and 0.010 +- 0.032 from another, with the same error; the truth was 0.010)
    lo, hi = problem.lo, problem.hi
    signs = np.where(np.arange(len(problem.free)) % 2 == 0, 1.0, -1.0)
    moved = np.clip(sol.x + signs * SECOND_START * (hi - lo), lo + problem.inset, hi - problem.inset)
    other = problem.solve(moved) if checked else sol
    if other.cost < sol.cost:
        sol, other = other, sol
    equal_fit = checked and other.cost <= (1.0 + EQUAL_FIT) ** 2 * sol.cost
    stds, determined, pressed = _verdicts(problem, sol, other, equal_fit=equal_fit, checked=checked)
    values = problem.values_at(sol.x)
    params, std, ident = _parameters(
        problem, values, [problem.raw(sol.x)[i] for i in range(problem.n_model)], stds, determined
    )
    pred = problem.predicted(sol.x)
    if problem.through_limits:
        refs = [
            float(sol.x[problem.n_model + problem.stepped.index(i)]) if i in problem.stepped else c.known_reference()
            for i, c in enumerate(fit)
        ]
        held_pred = [limited_output(model, values, c)[0] for c in held]
    else:
        refs = simulate_references(model, values, fit)
        held_pred = simulate_cases(model, values, held)
    held_rmse = rmse(held, held_pred) if held else None
    return ControlFit(
        model.name,
        model.kind,
        params,
        std,
        ident,
        rmse(fit, pred),
        held_rmse,
        None,
        False,
        "",
        {c.name: r for c, r in zip(fit, refs) if c.stepped},
        limits=problem.limits,
        pressed=pressed,
    )


class _FitProblem:
    """A model's constants (the fitted ones, the limits freed, the stepped cases' references when
    played through limits) as the solver's vector: log scale for those bounded above 0."""

    def __init__(
        self,
        model: ControlModel,
        fit: Sequence[ControlCase],
        limits: Limits,
        held_limits: dict[str, float],
        played_through_limits: bool,
    ) -> None:
        self.model, self.fit, self.limits, self.held_limits = model, fit, limits, held_limits
        self.through_limits = bool(limits or held_limits or played_through_limits)
        self.bounded = [
            replace(q, default=limits[q.name][0], low=limits[q.name][1], high=limits[q.name][2], limit=False)
            for q in model.parameters
            if q.name in limits
        ]
        self.n_model = len(model.fitted()) + len(self.bounded)
        through = self.through_limits
        self.stepped = [i for i, c in enumerate(fit) if c.stepped and c.reference is None] if through else []
        self.references = [
            ControlParameter(f"reference {fit[i].name}", "pu", 0.0, *REFERENCE_SEARCH, "the case's reference step")
            for i in self.stepped
        ]
        self.free = [*model.fitted(), *self.bounded, *self.references]
        self.values0 = model.defaults() | open_limits(model) | held_limits
        self.log = [p.low > 0 for p in self.free]
        self.lo = np.array([math.log(p.low) if lg else p.low for p, lg in zip(self.free, self.log)])
        self.hi = np.array([math.log(p.high) if lg else p.high for p, lg in zip(self.free, self.log)])
        # least_squares' trust region does not leave a bound it starts on (IEEET1's T_R stayed at 0
        # and T_A took both lags, +40 %): every start is moved inside by 2 % of its range
        self.inset = 0.02 * (self.hi - self.lo)

    def raw(self, x: Array) -> list[float]:
        """The vector's values in the constants' own terms."""
        return [float(np.exp(xi)) if lg else float(xi) for xi, lg in zip(x, self.log)]

    def values_at(self, x: Array) -> dict[str, float]:
        v = dict(self.values0)
        for p, xi, lg in zip(self.free[: self.n_model], x, self.log):
            v[p.name] = float(np.exp(xi)) if lg else float(xi)
        return self.model.completed(v)

    def wall(self) -> list[Array]:
        return [c.output + OUTSIDE_LIMITS * np.maximum(np.ptp(c.output), 1e-3) for c in self.fit]

    def predicted(self, x: Array) -> list[Array]:
        values = self.values_at(x)
        if not self.through_limits:
            out = simulate_cases(self.model, values, self.fit)
        else:
            refs = dict(zip(self.stepped, (float(r) for r in x[self.n_model :])))
            try:
                out = [
                    limited_output(self.model, values, c, refs.get(i, c.known_reference()))[0]
                    for i, c in enumerate(self.fit)
                ]
            except LimitsError:
                # limits that cannot hold an operating point at these constants (an input limit below
                # E_fd / K_A as K_A falls): a wall the search turns back from, not an answer
                return self.wall()
        # a play that diverged at these constants (a build-up's ceiling through an input limit on
        # Zakucac's day): a wall too; least_squares stopped with "Residuals are not finite"
        return out if all(np.all(np.isfinite(p)) for p in out) else self.wall()

    def residual(self, x: Array) -> Array:
        return np.concatenate([c.output - p for c, p in zip(self.fit, self.predicted(x))])

    def start(self, earlier: Mapping[str, Mapping[str, float]] | None, start_at: Mapping[str, float] | None) -> Array:
        """Where the solver starts: ``start_at``, else where ``model.start`` says from the
        ``earlier`` fits; the freed limits at their found values, the references where the
        small-signal model sizes them; moved inside the bounds."""
        model, free, log = self.model, self.free, self.log
        first = {**model.defaults(), **start_at} if start_at else model.start(earlier or {})
        first |= {q.name: q.default for q in self.bounded if not (start_at and q.name in start_at)}
        if self.stepped:  # the references start where the small-signal model sizes them
            cases = [self.fit[i] for i in self.stepped]
            lin = simulate_references(model, model.completed({**self.values0, **first}), cases)
            first |= {q.name: min(max(r, q.low), q.high) for q, r in zip(self.references, lin)}
        x0 = np.array([math.log(max(first[p.name], p.low)) if lg else first[p.name] for p, lg in zip(free, log)])
        return np.clip(x0, self.lo + self.inset, self.hi - self.inset)

    # the cases' rows (every sample of every case) compressed to k + 1 for the solver: its SVD of
    # the full Jacobian at every step was half the exciter search of a commissioning day
    def solve(self, start: Array) -> tall_least_squares.Solution:
        return tall_least_squares.solve(self.residual, start, self.lo, self.hi, MAX_EVALUATIONS)

    def solve_fixed(self, i: int, value: float, start: Array) -> float:
        """The least cost with constant ``i`` held at ``value``, the others refitted from ``start``."""
        keep = np.arange(len(self.free)) != i

        def res(y: Array) -> Array:
            x = start.copy()
            x[keep], x[i] = y, value
            return self.residual(x)

        return tall_least_squares.solve(res, start[keep], self.lo[keep], self.hi[keep], PROFILE_EVALUATIONS).cost


def _verdicts(
    problem: _FitProblem, sol: Any, other: Any, *, equal_fit: bool, checked: bool
) -> tuple[list[float], list[bool], list[str]]:
    """Per constant of the model its std and whether the data determine it; the limits the fit
    pressed on an end of their range."""
    model, free, log, lo, hi, n_model = (
        problem.model,
        problem.free,
        problem.log,
        problem.lo,
        problem.hi,
        problem.n_model,
    )
    fit = problem.fit
    # the residuals of one scenario are correlated (its dynamics, the smoothing): clustered by
    # scenario, not the textbook s^2 (J'J)^-1, which gave T_E 0.0468 +- 0.0001 for a true 0.05
    blocks = block_ids([c.output.size for c in fit], max(c.output.size for c in fit))
    cov = cluster_robust_cov(np.asarray(sol.jac), np.asarray(sol.fun), blocks)
    std_x = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    at_bound = (np.abs(sol.x - lo) < 1e-6) | (np.abs(sol.x - hi) < 1e-6)
    # a limit's range ends where the recordings say it cannot be (inside what the output reached,
    # or an operating point it held): one pressed within a thousandth of that end is flagged
    # (Mostar's V_RMIN sat 0.0003 from the lowest the output went, "determined")
    edge = 1e-3 * (hi - lo)
    ends = {n for pair in (model.output_limits, model.input_limits) if pair is not None for n in pair}
    pressed = []
    for i in range(len(model.fitted()), n_model):
        at_edge = bool(min(sol.x[i] - lo[i], hi[i] - sol.x[i]) < edge[i])
        at_bound[i] |= at_edge
        if at_edge and free[i].name in ends:
            pressed.append(free[i].name)
    # the Jacobian's std is local: where the error hardly changes with a constant moved by
    # DETERMINED_STD either way (the others refitted), the data do not determine it (HYGOV's T_r
    # on 12 s windows: 4.407 +- 0.21 for a true 5.0, the truth's error 0.02 % above the fit's).
    # "Hardly": less than two standard errors' worth of chi-square, 4/N_eff, N_eff the residuals'
    # count shrunk by their lag-1 correlation
    r = np.asarray(sol.fun, float)
    rho = float(np.clip(np.dot(r[1:], r[:-1]) / max(float(np.dot(r, r)), 1e-300), 0.0, 0.99))
    significant = 4.0 / max(r.size * (1.0 - rho) / (1.0 + rho), 1.0)
    raw, raw_other = problem.raw(sol.x), problem.raw(other.x)
    stds, determined = [], []
    # a time constant is known to a quarter of the fit's sample at best (1 ms at 250 Hz): a
    # limiter switches somewhere within a step of whatever made the recording (ANDES's 2 ms put
    # T_R 0.0179 and T_A 0.0223 for 0.02 each, T_A's Jacobian std 26 us)
    resolution = 0.25 * min(c.inputs.dt for c in fit)
    for i in range(n_model):  # the references are the cases' own, not the model's: not judged
        sd = raw[i] * float(std_x[i]) if log[i] else float(std_x[i])
        if free[i].unit == "s":
            sd = max(sd, resolution)
        scale = DETERMINED_STD * max(abs(raw[i]), 1e-9)
        ok = not at_bound[i] and math.isfinite(sd) and sd <= scale
        ok = ok and (not equal_fit or abs(raw_other[i] - raw[i]) <= scale)
        ok = ok and (not checked or _profile_rise(problem.solve_fixed, sol, i, log[i], lo, hi) >= significant)
        stds.append(sd)
        determined.append(ok)
    return stds, determined, pressed


def _parameters(
    problem: _FitProblem, values: dict[str, float], raw: list[float], stds: list[float], determined: list[bool]
) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, bool]]:
    """The fit's values, stds and verdicts by name: a limit never reached, and a constant the
    model's structure sets, given as not determined."""
    params: dict[str, float | None] = {}
    std: dict[str, float | None] = {}
    ident: dict[str, bool] = {}
    for i, p in enumerate(problem.free[: problem.n_model]):
        # where the model's completion moved a value to another name (IEEEG1's commuting lags,
        # put in order), its std and verdict go with it
        j = next((k for k, v in enumerate(raw) if v == values[p.name]), i)
        params[p.name], std[p.name], ident[p.name] = values[p.name], stds[j], bool(determined[j])
    for p in problem.model.parameters:
        if p.limit and p.name in problem.held_limits:  # found by the fit with the faults (the caller's verdict)
            params[p.name], std[p.name], ident[p.name] = problem.held_limits[p.name], None, False
        elif p.limit and p.name not in problem.limits:  # never reached: the data say nothing of it
            params[p.name], std[p.name], ident[p.name] = None, None, False
        elif p.held:  # the model's structure sets it (a stage left out, a share that completes another)
            params[p.name], std[p.name], ident[p.name] = values[p.name], None, False
    return params, std, ident


def _profile_rise(solve_fixed: Any, sol: Any, i: int, log: bool, lo: Array, hi: Array) -> float:
    """The least relative rise of the fit's cost with constant ``i`` moved by DETERMINED_STD either
    way and the others refitted."""
    rises = []
    for sign in (-1.0, 1.0):
        x = float(sol.x[i])
        moved = x + sign * math.log1p(DETERMINED_STD) if log else x * (1.0 + sign * DETERMINED_STD)
        if not lo[i] <= moved <= hi[i]:
            continue
        rises.append(solve_fixed(i, moved, np.asarray(sol.x, float)) / float(sol.cost) - 1.0)
    return min(rises) if rises else math.inf


def known_values(f: ControlFit) -> dict[str, float]:
    return {k: v for k, v in f.parameters.items() if v is not None}
