"""Which parameters the data determine: a two-point profile likelihood on the final model."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from phid_ros.cluster import Jobs
from phid_ros.diagnose.fit import Array, FitError, FitResult, ModelSpec, Problem, fit
from phid_ros.diagnose.options import DiagnoseOptions
from phid_ros.diagnose.screening import held_score
from phid_ros.ident.results import MAX_RELATIVE_STD
from phid_ros.ident.scenario import ScenarioData
from phid_ros.model.parameters import PARAMETER_NAMES

PROFILE_STEP = 0.10  # a base parameter is held this far (relative) from its fitted value


EFFECT_TOLERANCE = 0.01  # an effect parameter moving less than this (relative) along a flat valley stays determined


EffectValues = dict[str, dict[str, float]]  # effect -> its numeric parameters, of one fit


def determined(
    res: FitResult,
    fit_w: Sequence[ScenarioData],
    held_w: Sequence[ScenarioData],
    sigma: Mapping[str, float],
    opt: DiagnoseOptions,
    jobs: Jobs,
) -> tuple[dict[str, float], dict[str, bool], dict[str, dict[str, bool]], list[str]]:
    """Which parameters of the final model the data determine: a two-point profile of each base
    parameter, and what the named effects' parameters do along it.

    The Jacobian's standard deviations describe the valley's width where the fit sits, not how
    far a nearly flat valley runs: on ANDES's GENROU with dampers (T''_q0 within a factor 2 of
    T'_q0) the fit put X'_q at +15 % or +63 % depending on its path, with held-out errors equal
    to five digits, while the linearised std said 2.6 %. So each free base parameter is held
    PROFILE_STEP below and above its value while the rest refit; when on either side the held-out
    unexplained mean square rises by less than ``min_heldout_drop`` noise variances (the yardstick
    by which effects are named), the data do not determine it to PROFILE_STEP.

    The effects' parameters ride the same valleys: on that GENROU X''_q came out 0.2787 with a std
    of 0.0004 where the machine has 0.25, and in the refits the held-out data could not tell from
    the best it moved to 0.2733-0.2856. An effect parameter that moves, in any refit the held-out
    data cannot tell from the best, by more than twice its std and more than EFFECT_TOLERANCE of
    its value is not determined either: its value and std would be a wrong number published as
    identified.
    """
    f_hz = opt.f_nominal_hz
    base = held_score(res.model, held_w, sigma, f_hz).overall ** 2
    names = [n for n in PARAMETER_NAMES if n not in opt.held]
    points = [(n, k) for n in names for k in (1.0 - PROFILE_STEP, 1.0 + PROFILE_STEP)]
    outcomes = jobs.map(_profile_point, [(res, n, k, fit_w, held_w, sigma, opt) for n, k in points])
    rise: dict[str, float] = {}
    for (n, _), (sc, _) in zip(points, outcomes):
        # a point that could not be simulated (NaN) leaves its parameter not determined
        rise[n] = math.nan if math.isnan(sc) or math.isnan(rise.get(n, 0.0)) else min(rise.get(n, math.inf), sc - base)
    uncertainty: dict[str, float] = {}
    identifiable: dict[str, bool] = {}
    notes: list[str] = []
    for n, v in res.model.base.items():
        if n in opt.held:  # the caller's value, identified before the diagnosis
            uncertainty[n], identifiable[n] = math.nan, True
            continue
        std = res.base_std.get(n, math.nan)
        uncertainty[n] = std
        linear_ok = math.isfinite(std) and abs(v) > 0 and std / abs(v) <= MAX_RELATIVE_STD
        identifiable[n] = bool(linear_ok and rise[n] >= opt.min_heldout_drop)
        if not identifiable[n] and math.isnan(rise[n]):
            notes.append(
                f"{n} = {v:.4g} not determined: held {100 * PROFILE_STEP:.0f} % away, the model could not be "
                "simulated (the play-in diverged), so the data were not asked"
            )
        elif not identifiable[n]:
            notes.append(
                f"{n} = {v:.4g} not determined by these data: held {100 * PROFILE_STEP:.0f} % away, the other "
                f"parameters refit to a held-out error {rise[n]:+.3f} noise variances from the best"
            )
    alike = [values for sc, values in outcomes if sc - base < opt.min_heldout_drop]
    effects_identifiable, effect_notes = effects_determined(res, alike)
    return uncertainty, identifiable, effects_identifiable, notes + effect_notes


def effects_determined(res: FitResult, alike: Sequence[EffectValues]) -> tuple[dict[str, dict[str, bool]], list[str]]:
    """Per named effect, whether each numeric parameter stays put in the refits ``alike`` (those
    the held-out data cannot tell from the final fit ``res``): see :func:`determined`."""
    stds = res.effect_std or [{} for _ in res.model.effects]
    flags: dict[str, dict[str, bool]] = {}
    notes: list[str] = []
    for (cand, values), std in zip(res.model.effects, stds):
        name = cand.name()
        flags[name] = {}
        for p, v in values.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                continue  # a form or a curve's name: chosen, not estimated
            seen = [fx[name][p] for fx in alike if p in fx.get(name, {})]
            move = max((abs(x - float(v)) for x in seen), default=0.0)
            sd = float(std.get(p, math.nan))
            limit = max(2.0 * sd if math.isfinite(sd) else 0.0, EFFECT_TOLERANCE * abs(float(v)))
            flags[name][p] = bool(move <= limit)
            if not flags[name][p]:
                lo, hi = min(seen), max(seen)
                notes.append(
                    f"{name} {p} = {float(v):.4g} not determined by these data: in refits the held-out data "
                    f"cannot tell from the best it moves to {lo:.4g}-{hi:.4g} (its std {sd:.2g})"
                )
    return flags, notes


def _profile_point(
    final: FitResult,
    name: str,
    factor: float,
    fit_w: Sequence[ScenarioData],
    held_w: Sequence[ScenarioData],
    sigma: Mapping[str, float],
    opt: DiagnoseOptions,
) -> tuple[float, EffectValues]:
    """Held-out unexplained mean square with ``name`` held at ``factor`` times its value, and the
    refit's effect parameters there (one job)."""
    spec = final.model
    moved = ModelSpec({**spec.base, name: spec.base[name] * factor}, list(spec.effects))
    p = Problem(fit_w, sigma, moved, opt.f_nominal_hz, wide=opt.wide, held=(*opt.held, name))
    try:
        res = fit(p, opt.max_nfev, profile_start(final, p, name, factor))
    except FitError:  # the model cannot be simulated there: the point tells nothing, so not determined
        return math.nan, {}
    values = {
        c.name(): {k: float(v) for k, v in vals.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
        for c, vals in res.model.effects
    }
    return held_score(res.model, held_w, sigma, opt.f_nominal_hz).overall ** 2, values


def profile_start(final: FitResult, p: Problem, name: str, factor: float) -> Array | None:
    """Where the other parameters go when ``name`` moves by ``factor``, to first order: the
    least-squares step of the final fit's Jacobian that answers that move.

    Why: from the final values alone, a profile point's refit walked the length of a valley
    (X'_d against T'_d0) in 15-24 evaluations; the linear prediction starts it near the floor.
    The refit still converges by the solver's own criteria, only in fewer steps.
    """
    keys = [(i, q.name) for i, q in final.free]
    if final.jac is None or final.x is None or (-1, name) not in keys:
        return None
    j = keys.index((-1, name))
    moved = final.free[j][1].to_x(final.model.base[name] * factor) - final.x[j]
    others = [keys.index((i, q.name)) for i, q in p.free if (i, q.name) in keys]
    if len(others) != len(p.free):
        return None
    step = np.linalg.lstsq(final.jac[:, others], -final.jac[:, j] * moved, rcond=None)[0]
    return final.x[others] + step
