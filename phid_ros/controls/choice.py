"""The choice among a kind's fitted models: the simplest of those that answer the held-out
recordings best, named only if it explains clearly more than "no control action" (the output
moving only with the reference steps): the diagnosis's rule against naming what the data do not
show. A term the recordings do not show is held where it vanishes before the named model's
constants are checked."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

from phid_ros.controls.cases import ControlCase
from phid_ros.controls.fit import EQUAL_FIT, ControlFit
from phid_ros.controls.limits import refit_through_limits
from phid_ros.controls.models import MODELS, ControlModel, ControlParameter

SIMPLEST_WITHIN = 1.05  # a model with more constants is chosen only where it errs 5 % less than a simpler one
NAMED_BELOW = 0.75  # a model is named when its held-out error is below this share of "no control action"


def _holding(model: ControlModel, name: str) -> ControlModel:
    """``model`` with constant ``name`` held where its term vanishes, and the constants of that
    term (a rate feedback's T_F with its K_F) held with it: moot."""

    def held(p: ControlParameter) -> ControlParameter:
        if p.name == name and p.absent is not None:
            return replace(p, default=p.absent, low=p.absent, high=p.absent, held=True)
        return replace(p, held=True) if p.within == name else p

    return model.with_parameters(held(p) for p in model.parameters)


def without_unseen_terms(
    model: ControlModel, fitted: ControlFit, fit: Sequence[ControlCase], held: Sequence[ControlCase]
) -> ControlModel:
    """The model with each term the recordings do not show held where it vanishes, one at a time
    while the fit's error rises by less than ``EQUAL_FIT``: a rate feedback of a static exciter
    that has none (EXST1 with K_F = 0) otherwise trades with its lead-lag, and neither is
    determined."""
    for p in model.parameters:
        if p.absent is None or p.held or p.limit:
            continue
        trial = _holding(model, p.name)
        f = refit_through_limits(trial, fitted, fit, held, checked=False)
        if f.fit_rmse <= (1.0 + EQUAL_FIT) * fitted.fit_rmse:
            model, fitted = trial, f
    return model


def judged(f: ControlFit) -> float:
    """A fit's error as the choice sees it: held out, or its own without validation scenarios."""
    e = f.heldout_rmse if f.heldout_rmse is not None else f.fit_rmse
    return e if math.isfinite(e) else math.inf


def simplest_best(fits: Sequence[ControlFit]) -> tuple[ControlFit, list[ControlFit]]:
    """The fit with the fewest fitted constants among those within ``SIMPLEST_WITHIN`` of the best
    error (registration order among equals), and the others within it: a model that nests another
    (EXST1 with T_R and K_F at 0 is SEXS) fits its data as well, and the data do not show the extra
    blocks; two that do not nest may still answer alike (IEEET1's rate feedback around a large
    K_A is EXST1's transient gain reduction), and the recordings cannot tell them apart."""
    best = min(judged(f) for f in fits)
    close = [f for f in fits if judged(f) <= SIMPLEST_WITHIN * best]
    chosen = min(close, key=lambda f: len(MODELS[f.model].fitted()))
    return chosen, [f for f in close if f is not chosen]
