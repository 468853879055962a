"""Naming the missing physics: greedy forward selection over the candidate library.

Start from the identified fourth-order model, refitted by output error on the
fit windows (so every later comparison is between models fitted the same way).
Each round, every candidate not yet in the model is screened (a grid over its
own parameters with the current model held) and the best few are fitted with
all base and effect parameters free. A candidate is named only when both
pieces of evidence agree it is real:

- the Bayesian information criterion on the fit windows improves by more than
  ``bic_margin`` (the penalty for its extra parameters is already inside BIC;
  the margin guards against the residual's time correlation, which makes the
  chi-square differences larger than independent samples would);
- the unexplained mean square on scenarios held out of the fit falls by at least
  ``min_heldout_drop`` noise variances (an effect that only fits the noise of the
  fit windows does not carry over). The drop is absolute, not relative: when two
  effects are missing, the smaller one explains a small share of the total gap
  and must still be named;
- the effect's own estimate stands ``min_presence_sigma`` standard deviations
  away from the value at which it vanishes (its confidence interval excludes
  "absent"), where its parameters declare one;
- after the first effect, a further one must explain ``min_remaining_share`` of
  the held-out error that remains: an imperfect model of the first leaves a
  structured residual of which any flexible candidate absorbs a little.

The winner becomes the new model and the next round looks for a second effect;
the search stops when no candidate passes. With nothing missing it names none.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from phid_ros import jit
from phid_ros.cluster import Jobs, one_blas_thread
from phid_ros.diagnose.candidates import library
from phid_ros.diagnose.determinability import determined
from phid_ros.diagnose.fit import FitResult, ModelSpec, fit
from phid_ros.diagnose.options import DiagnoseOptions
from phid_ros.diagnose.outcome import Diagnosis, Round, Score, Trial
from phid_ros.diagnose.screening import held_score, problem, screen
from phid_ros.diagnose.trials import candidate_names, conflicts, fit_cost, passes, starting_point, trial, unresolved
from phid_ros.diagnose.windows import channel_sigma, check_measurements, split, window
from phid_ros.ident.plant_playin import play_in
from phid_ros.ident.scenario import ScenarioData
from phid_ros.model.parameters import PARAMETER_NAMES


def _round_trials(
    pool: list[Any],
    current: FitResult,
    current_score: Score,
    fit_w: list[ScenarioData],
    held_w: list[ScenarioData],
    sigma: Mapping[str, float],
    opt: DiagnoseOptions,
    jobs: Jobs,
    say: Callable[[str], None],
) -> list[Trial]:
    """One round's candidates: each screened on the current model's play-in, the best few fitted
    with the base parameters and scored on held-out data (the rest listed, unfitted)."""
    say(f"screening {len(pool)} candidates: {candidate_names(pool)}")
    f_hz = opt.f_nominal_hz
    runs = play_in(fit_w, current.model.base, current.model.plant_effects(), f_nominal_hz=f_hz)
    found = jobs.map(screen, [(c, current.model, fit_w, sigma, f_hz, runs) for c in pool])
    screened = sorted(((chi2, c, v) for c, (v, chi2) in zip(pool, found)), key=lambda t: t[0])
    shortlist = [t for t in screened[: opt.shortlist] if math.isfinite(t[0])]  # inf: no admissible trial
    say(f"fitting {len(shortlist)} candidates with the base parameters: {candidate_names(c for _, c, _ in shortlist)}")
    longest_first = sorted(shortlist, key=lambda t: -fit_cost(t[1]))
    trials = jobs.map(
        trial,
        [(c, v, chi2, current, current_score, fit_w, held_w, sigma, opt) for chi2, c, v in longest_first],
    )
    trials.sort(key=lambda t: t.screened_chi2)
    return trials + [Trial(c.name(), {}, None, chi2) for chi2, c, _ in screened[len(shortlist) :]]


def _converged(
    best: Trial,
    fit_w: list[ScenarioData],
    held_w: list[ScenarioData],
    sigma: Mapping[str, float],
    opt: DiagnoseOptions,
    say: Callable[[str], None],
) -> tuple[FitResult, Score]:
    """The named model's fit, finished when its evaluation budget stopped it: what it had left to gain
    would be credited to whichever candidate comes next (seen: a stator resistance at its 0.001
    floor "explained" 83 % after saturation)."""
    assert best.fit is not None and best.heldout is not None
    current, score = best.fit, best.heldout
    for _ in range(3):
        if current.nfev < opt.max_nfev:
            break
        say(f"refitting the model with {best.candidate} to convergence")
        more = fit(problem(fit_w, sigma, current.model, opt), opt.max_nfev)
        if not more.chi2 < current.chi2:
            break
        current = more
        score = held_score(current.model, held_w, sigma, opt.f_nominal_hz)
    return current, score


def _not_determined_when_unexplained(score: Score, identifiable: dict[str, bool], opt: DiagnoseOptions) -> str:
    """A final model that still leaves much unexplained: its base parameters absorb what it misses.

    GENSAL's saturation form on GENROU's machine: named, 6.7 sigma left, and X_q -29 % and T'_q0
    -34 % "determined" by the profile: determined by a model that is still wrong.
    """
    unsure = [n for n in PARAMETER_NAMES if n not in opt.held and identifiable.get(n)]
    identifiable.update({n: False for n in unsure})
    return (
        f"the final model leaves {score.overall:.2f} noise sigma unexplained on held-out data "
        f"(more than {opt.max_unexplained:g}): its base parameters absorb what it still misses and are "
        "not given as determined"
    )


def diagnose(
    scenarios: Sequence[ScenarioData],
    identified: Mapping[str, float],
    options: DiagnoseOptions | None = None,
    progress: Callable[[str], None] | None = None,
) -> Diagnosis:
    """Name the effects missing from the model ``identified`` (the eight base parameters).

    With one BLAS thread: the play-ins' threads hold the cores (BLAS threads on top spin and
    oversubscribe them), and OpenBLAS rounds differently with other thread counts, so a
    diagnosis in this process gives the same digits with any number of workers.
    """
    with one_blas_thread():
        return _diagnose(scenarios, identified, options, progress)


def _diagnose(
    scenarios: Sequence[ScenarioData],
    identified: Mapping[str, float],
    options: DiagnoseOptions | None,
    progress: Callable[[str], None] | None,
) -> Diagnosis:
    opt = options or DiagnoseOptions()
    say = progress or (lambda msg: None)
    t_start = time.perf_counter()
    f_hz = opt.f_nominal_hz
    fit_s, held_s = split(scenarios, opt.per_kind)
    fit_w = [window(s, opt.pre_s, opt.post_s) for s in fit_s]
    held_w = [window(s, opt.pre_s, opt.post_s) for s in held_s]
    sigma = channel_sigma(scenarios)
    check_measurements(scenarios, sigma)

    say("refitting the fourth-order model by output error")
    start, problems = starting_point(identified)
    current = fit(problem(fit_w, sigma, ModelSpec(start), opt), opt.max_nfev)
    base_fit = current
    current_score = before = held_score(current.model, held_w, sigma, f_hz)
    rounds: list[Round] = []
    steps: list[tuple[str, Score]] = []
    # threads where the play-ins run compiled without the GIL: the speed of processes, a third of the memory
    with Jobs(opt.workers, opt.scheduler, threads=jit.available()) as jobs:
        while len(current.model.effects) < opt.max_effects:
            taken = set(current.model.names)
            pool = [c for c in library() if c.name() not in taken and not conflicts(c, current.model)]
            if not pool:
                break
            trials = _round_trials(pool, current, current_score, fit_w, held_w, sigma, opt, jobs, say)
            passing = [t for t in trials if t.fit is not None and passes(t, current_score, bool(steps), opt)]
            problems.extend(unresolved(trials))
            if not passing:
                rounds.append(Round(trials, None))
                break
            best = min(passing, key=lambda t: t.delta_bic)
            best.accepted = True
            current, current_score = _converged(best, fit_w, held_w, sigma, opt, say)
            steps.append((best.candidate, current_score))
            rounds.append(Round(trials, best.candidate))
            say(f"named {best.candidate}: BIC {best.delta_bic:+.0f}, held-out error -{100 * best.heldout_gain:.0f} %")
        say("profiling the final model: which base parameters do the data determine")
        uncertainty, identifiable, effects_identifiable, notes = determined(current, fit_w, held_w, sigma, opt, jobs)
        problems.extend(notes)
    if current_score.overall > opt.max_unexplained:
        problems.append(_not_determined_when_unexplained(current_score, identifiable, opt))
    return Diagnosis(
        identified={n: float(identified.get(n, math.nan)) for n in PARAMETER_NAMES},
        identified_at_bound=tuple(opt.wide),
        base_fit=base_fit,
        final=current,
        rounds=rounds,
        before=before,
        after=current_score,
        steps=steps,
        fit_windows=fit_w,
        heldout_windows=held_w,
        sigma=sigma,
        seconds=time.perf_counter() - t_start,
        problems=problems,
        identifiable=identifiable,
        uncertainty=uncertainty,
        held=list(opt.held),
        effects_identifiable=effects_identifiable,
    )
