"""Scoring a model on held-out windows and screening a candidate effect with the current model held."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from phid_ros.diagnose.candidates import Candidate
from phid_ros.diagnose.fit import Array, ModelSpec, Problem, chi_square
from phid_ros.diagnose.localise import noise_std
from phid_ros.diagnose.options import DiagnoseOptions
from phid_ros.diagnose.outcome import ChannelError, Score
from phid_ros.ident.plant_playin import OUTPUTS, PlayIn, play_in
from phid_ros.ident.scenario import ScenarioData


def score(runs: Sequence[PlayIn], sigma: Mapping[str, float], col: int = 0) -> Score:
    channels = {}
    for c in OUTPUTS:
        r = np.concatenate([x.sim[c][:, col] - x.meas[c][:, col] for x in runs])
        ms = float(np.mean(r**2))
        white = float(np.mean([noise_std(x.sim[c][:, col] - x.meas[c][:, col]) ** 2 for x in runs]))
        channels[c] = ChannelError(math.sqrt(ms), math.sqrt(max(ms - white, 0.0)))
    overall = math.sqrt(np.mean([(channels[c].unexplained / sigma[c]) ** 2 for c in OUTPUTS]))
    return Score(channels, overall)


def screen(
    cand: type[Candidate],
    current: ModelSpec,
    windows: Sequence[ScenarioData],
    sigma: Mapping[str, float],
    f_hz: float,
    runs: Sequence[PlayIn] = (),
) -> tuple[dict[str, Any], float]:
    """Best trial values of ``cand`` added to ``current`` (which is held fixed), and their chi-square.

    ``runs`` is the current model's play-in on ``windows``: a candidate may read its
    signature in the residual to place its grid (a torsional frequency, for one).
    """
    grid = cand.screen(runs)
    ok = cand.admissible(grid, current.base)
    best: tuple[dict[str, Any], float] = ({}, math.inf)
    if not ok.any():
        # no trial describes a machine with the current base (seen on noise-free STEPS data, two
        # loadings: numpy's "argmin of an empty sequence" ended the diagnosis): not a candidate now
        return best
    grid = {k: v[ok] for k, v in grid.items()}

    def trial(grid: dict[str, Array], setting: dict[str, str]) -> tuple[dict[str, Any], float]:
        m = len(next(iter(grid.values())))
        effects = current.plant_effects() + [(cand.effect, {**grid, **setting})]
        chi2 = chi_square(windows, sigma, current.base, effects, m, f_hz)
        j = int(np.argmin(chi2))
        return {**{k: float(v[j]) for k, v in grid.items()}, **setting}, float(chi2[j])

    for setting in cand.choices():
        found = trial(grid, setting)
        if found[1] < best[1]:
            best = found
    finer = cand.refine(best[0])
    if finer is not None:
        setting = {k: v for k, v in best[0].items() if isinstance(v, str)}
        found = trial(finer, setting)
        if found[1] < best[1]:
            best = found
    return best


def screen_jointly(
    cand: type[Candidate],
    joint: tuple[dict[str, Array], dict[str, Array]],
    current: ModelSpec,
    windows: Sequence[ScenarioData],
    sigma: Mapping[str, float],
    f_hz: float,
) -> tuple[ModelSpec, float]:
    """The best of the candidate's joint trials (effect and base values per column)."""
    values, base = joint
    m = len(next(iter(base.values())))
    effects = current.plant_effects() + [(cand.effect, values)]
    chi2 = chi_square(windows, sigma, base, effects, m, f_hz)
    j = int(np.argmin(chi2))
    spec = ModelSpec(
        {k: float(v[j]) for k, v in base.items()},
        list(current.effects) + [(cand, {k: v if isinstance(v, str) else float(v[j]) for k, v in values.items()})],
    )
    return spec, float(chi2[j])


def held_score(spec: ModelSpec, held: Sequence[ScenarioData], sigma: Mapping[str, float], f_hz: float) -> Score:
    return score(play_in(held, spec.base, spec.plant_effects(), f_nominal_hz=f_hz), sigma)


def problem(
    windows: Sequence[ScenarioData],
    sigma: Mapping[str, float],
    spec: ModelSpec,
    opt: DiagnoseOptions,
    basin: bool = False,
) -> Problem:
    """The least-squares problem of ``spec`` on ``windows`` as the options free its base parameters."""
    return Problem(windows, sigma, spec, opt.f_nominal_hz, basin=basin, wide=opt.wide, held=opt.held)
