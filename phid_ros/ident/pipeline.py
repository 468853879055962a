"""The three-stage identification from prepared scenarios to one result (Algorithm 1).

Each stage that cannot run (too few scenarios of a kind, NaN windows, an
ill-posed fit) leaves its parameters as NaN with the reason in ``problems``;
nothing is filled in silently. Stage 3 takes X_d and X_q from stage 2, or,
when stage 2 cannot run, refines them itself (``fast`` only).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import ClassVar

from phid_ros.errors import StageError
from phid_ros.ident import consistency, determinable, validation
from phid_ros.ident.constraints import Constraints, at_user_bound, held
from phid_ros.ident.identification import (
    OPERATING_CHANNELS,
    IdentificationResult,
    IdentifyOptions,
    Say,
    operating_point,
)
from phid_ros.ident.results import Estimate
from phid_ros.ident.route_figures import QAxisSearchFigures
from phid_ros.ident.routes import Route, RouteOutput, RouteRun, run_plan
from phid_ros.ident.scenario import ScenarioData, file_of
from phid_ros.ident.stages import (
    DifferentialDamping,
    Ieee115CurveFits,
    SteadyStateReactances,
    SwingRegression,
    stage3_methods,
)
from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME, GeneratorParameters

# what the rest of phid imports from here: the identification's options and result
__all__ = ["OPERATING_CHANNELS", "IdentificationResult", "IdentifyOptions", "identify", "operating_point", "prepare"]


def _apply_constraints(res: IdentificationResult, c: Constraints) -> None:
    """Held parameters reported as held; an estimate that ended on a user's bound flagged (stage 3's
    searches stop at the bound without saying how far beyond the data pulled)."""
    for name in PARAMETER_NAMES:
        if name in c.fixed:
            res.estimates[name] = held(name, c.fixed[name])
            continue
        est, b = res.estimates.get(name), c.bounds.get(name)
        if est is None or b is None or est.at_bound or not math.isfinite(est.value):
            continue
        if c.outside(name, est.value):  # a route that does not search within the bounds (a recorder's channels)
            est.disqualify(
                f"{name} = {est.value:.4g} lies outside the bounds {b[0]:g}:{b[1]:g} (--bounds): the data and "
                "the bounds disagree, not identified"
            )
            continue
        for bound in b:
            if abs(est.value - bound) <= 1e-3 * abs(bound):
                at_user_bound(est, name, math.nan, bound)


def _timed(timing: dict[str, float], key: str, t0: float) -> None:
    timing[key] = round(time.perf_counter() - t0, 6)


def prepare() -> None:
    """Compile (or load from numba's cache) every compiled part of an identification now: the
    filters' recursions, stage 3's kept-sample filter and the validation play-in.

    A first compile on a machine takes seconds, mostly in LLVM and holding the GIL: in the
    recalibration node's worker it would stall the sensor callbacks of its first run. The node
    calls this before it subscribes; elsewhere the first identification does it.
    """
    import numpy as np

    from phid_ros.numerics import all_pole, first_order_response_kept

    x = np.zeros((8, 2))
    all_pole(x, (-0.5,), axis=0)
    first_order_response_kept(x.T, 0.1, 1e-3, 5)
    validation.prepare()


def _withhold(res: IdentificationResult, suspicions: Sequence[consistency.Suspicion]) -> None:
    """What a suspected unit or convention mistake touches is not published as identified."""
    for sus in suspicions:
        res.problems.append(f"channels: {sus.message}")
        for name in sus.parameters:
            if name in res.estimates:
                res.estimates[name].disqualify(f"withheld: {sus.message}")


def _physical_ranges(res: IdentificationResult) -> None:
    """A value outside its declared physical range, or a transient reactance not below its
    synchronous one, is never published as identified, however small its std."""
    for name, est in res.estimates.items():
        problem = SPECS_BY_NAME[name].outside(est.value) if math.isfinite(est.value) else None
        if problem is not None and est.identifiable:
            est.disqualify(f"outside its physical range: {problem}")
    for small, large in (("X_d_prime", "X_d"), ("X_q_prime", "X_q")):
        a, b = res.estimates.get(small), res.estimates.get(large)
        if a is None or b is None or not (math.isfinite(a.value) and math.isfinite(b.value)):
            continue
        if not a.value < b.value:
            for est in (a, b):
                if est.identifiable:
                    est.disqualify(f"{small} = {a.value:.4g} is not below {large} = {b.value:.4g}")


def identify(
    scenarios: Sequence[ScenarioData],
    options: IdentifyOptions | None = None,
    truth: GeneratorParameters | None = None,
    progress: Callable[[str], None] | None = None,
) -> IdentificationResult:
    """The three stages (and the IEEE 115 baseline and validation when asked); ``progress`` hears each step.

    Each step below reads what the steps before it put in the result (X_d and X_q from stage 2
    or the user's held values, the baseline's transient estimates as the paper method's prior)
    and writes its own estimates, details and problems there; a step that cannot run says why.
    """
    opt = options or IdentifyOptions()
    say = progress or (lambda step: None)
    if opt.method not in stage3_methods():
        raise ValueError(f"method must be one of {tuple(stage3_methods())}, got {opt.method!r}")
    scs = list(scenarios)
    res = IdentificationResult({}, opt.method, scs, constraints=opt.constraints)
    for s in scs:
        if s.label_kept:
            res.label_disputes.append(f"{s.name}: {s.label_kept}")
    res.problems.extend(res.label_disputes)
    ident = [s for s in scs if s.role == "identify"]
    if not ident:
        res.problems.append("no identification scenarios: nothing to identify")
        return res
    say("checking the channels' units and conventions")
    findings = consistency.check(scs, opt.f_nominal_hz)
    consistency.raise_errors(findings)  # a unit or sign mistake: nothing identified from it is true
    if determinable.full_channels(ident):
        run_plan(PAPER_STEPS, RouteRun(res, ident, opt, say, {}))
    else:  # a recorder's channel set: what it determines, the rest named as not identifiable
        t0 = time.perf_counter()
        res.determined_by = determinable.identify_by_channels(res, ident, opt, say)
        _timed(res.timing, "by_channels", t0)
        t0 = time.perf_counter()
        _each_test_file_left_out(res, ident, opt, say)
        _timed(res.timing, "files_left_out", t0)
    _apply_constraints(res, opt.constraints)
    _withhold(res, findings.suspicions)
    _physical_ranges(res)
    for est in res.estimates.values():
        if not est.identifiable and est.note:
            res.problems.append(est.note)
    t0 = time.perf_counter()
    if opt.validate:
        _validate(res, scs, opt, say, truth)
    _timed(res.timing, "validation", t0)
    return res


MIN_FILES_LEFT_OUT = 3  # test files at least, for each to be left out in turn
# and at most: each costs an identification, and with more independent tests the fit's residuals
# already carry their spread (a commissioning day has a handful of files, a catalogue 15 scenarios)
MAX_FILES_LEFT_OUT = 10
LEFT_OUT_STDS = 2.0  # an estimate moving by more than this many stds with one file left out is withheld
# and by more than this share of its value: on a clean recording two routes' stds of 1e-4 would
# withhold an X_d that moves 0.04 % between them, which no planning study can tell
LEFT_OUT_NEGLIGIBLE = 0.005


def _each_test_file_left_out(
    res: IdentificationResult, ident: list[ScenarioData], opt: IdentifyOptions, say: Say
) -> None:
    """Each parameter given as identified from a recorder's channels, identified again with each
    test file left out in turn (``MIN_FILES_LEFT_OUT`` to ``MAX_FILES_LEFT_OUT`` files): one
    that moves by more than ``LEFT_OUT_STDS`` of the two stds (in quadrature) is withheld, with
    the file that moves it. The std of one fit does not see what the choice of tests moves (on a
    real commissioning day, X_d moved 16 % with the cut while its std said 1-3 %). A file whose
    absence leaves a parameter undetermined says nothing of it."""
    given = [n for n, e in res.estimates.items() if e.identifiable and n not in opt.constraints.fixed]
    files: dict[str, list[ScenarioData]] = {}
    for s in ident:
        files.setdefault(file_of(s), []).append(s)
    if not given or not MIN_FILES_LEFT_OUT <= len(files) <= MAX_FILES_LEFT_OUT:
        return
    say(f"each of {len(files)} test files left out in turn: does an estimate move?")
    sub_opt = _with_q_axis_of(res, opt)
    for name_of_file in files:
        rest = [s for s in ident if file_of(s) != name_of_file]  # by name: a scenario's == compares arrays
        sub = IdentificationResult({}, opt.method, rest, constraints=sub_opt.constraints)
        determinable.identify_by_channels(sub, rest, sub_opt, lambda _step: None)
        for n in given:
            e, o = res.estimates[n], sub.estimates.get(n)
            if not e.identifiable or o is None or not (math.isfinite(o.value) and math.isfinite(o.std)):
                continue
            spread = max(LEFT_OUT_STDS * math.hypot(e.std, o.std), LEFT_OUT_NEGLIGIBLE * abs(e.value))
            if abs(o.value - e.value) > spread:
                e.disqualify(
                    f"{n} {e.value:.4g} ± {e.std:.2g} moves to {o.value:.4g} ± {o.std:.2g} with {name_of_file}'s "
                    f"tests left out (more than {LEFT_OUT_STDS:g} stds): the tests do not agree on it"
                )


def _with_q_axis_of(res: IdentificationResult, opt: IdentifyOptions) -> IdentifyOptions:
    """The options with the q axis the whole set's d-axis residual chose held (a subset's own
    search costs most of its fit and only steers the rotor angle's reconstruction): its X'_q and
    T'_q0, or at rest (X'_q = X_q: the static reconstruction)."""
    chosen = res.route_details.get("q_axis_search")
    x_q = opt.constraints.fixed.get("X_q")
    if not isinstance(chosen, QAxisSearchFigures) or x_q is None:
        return opt
    q = chosen.q_transient or (x_q, 1.0)
    fixed = {**opt.constraints.fixed, "X_q_prime": float(q[0]), "T_q0_prime": float(q[1])}
    return replace(opt, constraints=replace(opt.constraints, fixed=fixed))


def _stage1(res: IdentificationResult, ident: list[ScenarioData], opt: IdentifyOptions, say: Say) -> None:
    say("stage 1: H and D from the swing equation")
    try:
        out = SwingRegression(opt.stage1_cutoff_hz, opt.constraints).run(ident, {})
        res.stage1 = out.result
        res.estimates.update(out.estimates)
    except StageError as exc:
        res.problems.append(f"stage 1 (H, D) did not run: {exc}")
    if any(s.kind == "torque_step" and not s.generator_damping for s in ident):
        try:
            res.stage1_paper = DifferentialDamping().run(ident, {}).result
        except (StageError, RuntimeError) as exc:
            res.problems.append(f"paper's differential damping method did not run: {exc}")


def _stage2(res: IdentificationResult, ident: list[ScenarioData], opt: IdentifyOptions, say: Say) -> None:
    say("stage 2: X_d and X_q from the steady states")
    try:
        out = SteadyStateReactances().run(ident, {})
        res.stage2 = out.result
        res.estimates.update(out.estimates)
        res.problems.extend(f"stage 2: {p}" for p in out.problems)
        for name in ("X_d", "X_q"):  # each a line of its own: holding one leaves the other's fit as it is
            est = res.estimates[name]
            if opt.constraints.outside(name, est.value):
                wanted = est.value
                est.value = opt.constraints.clip(name, wanted)
                at_user_bound(est, name, wanted, est.value)
    except StageError as exc:
        res.problems.append(f"stage 2 (X_d, X_q) did not run: {exc}")
    for name in ("X_d", "X_q"):
        if name in opt.constraints.fixed:
            res.estimates[name] = held(name, opt.constraints.fixed[name])


def _synchronous(res: IdentificationResult) -> dict[str, float]:
    """X_d and X_q as stage 2 left them (identified, clipped to the user's bounds, or held), where they exist."""
    return {n: res.estimates[n].value for n in ("X_d", "X_q") if n in res.estimates}


def _baseline(res: IdentificationResult, ident: list[ScenarioData], opt: IdentifyOptions, say: Say) -> None:
    """The IEEE 115 curve fits; they need a reference X_d, X_q for their bounds (18), (21)."""
    known = _synchronous(res)
    if not opt.baseline or len(known) < 2:
        return
    say("IEEE 115 baseline: curve fits of the transients")
    try:
        out = Ieee115CurveFits(seed=opt.seed).run(ident, known)
        res.baseline = {n: Estimate(res.estimates[n].value) for n in ("H", "D", "X_d", "X_q") if n in res.estimates}
        res.baseline.update(out.estimates)
    except StageError as exc:
        res.problems.append(f"IEEE 115 baseline did not run: {exc}")


def _stage3(res: IdentificationResult, ident: list[ScenarioData], opt: IdentifyOptions, say: Say) -> None:
    say("stage 3: transient parameters by state consistency")
    try:
        method = stage3_methods()[opt.method].from_options(opt, res.baseline)
        out = method.run(ident, _synchronous(res))
        res.stage3 = out.result
        res.estimates.update(out.estimates)
        res.problems.extend(f"stage 3: {p}" for p in out.problems)
    except StageError as exc:
        res.problems.append(f"stage 3 (X'_d, X'_q, T'_d0, T'_q0) did not run: {exc}")


class PaperStep(Route):
    """A stage of the paper's on the full channel set as a step of the plan: it writes the result
    itself (held values are applied after the plan, not filtered out of its fit)."""

    how = ""
    step: ClassVar[Callable[[IdentificationResult, list[ScenarioData], IdentifyOptions, Say], None]]

    def run(self, run: RouteRun) -> RouteOutput:
        type(self).step(run.res, run.ident, run.opt, run.say)
        return RouteOutput()


class Stage1(PaperStep):
    key, parameters, step = "stage1", ("H", "D"), _stage1


class Stage2(PaperStep):
    key, parameters, step = "stage2", ("X_d", "X_q"), _stage2


class Baseline(PaperStep):
    key, parameters, step = "ieee115", (), _baseline


class Stage3(PaperStep):
    key, parameters, step = "stage3", ("X_d_prime", "X_q_prime", "T_d0_prime", "T_q0_prime"), _stage3


# the paper's plan (Algorithm 1), each step timed under its key (the JSON's timing_s)
PAPER_STEPS: tuple[Route, ...] = (Stage1(), Stage2(), Baseline(), Stage3())


def _validate(
    res: IdentificationResult,
    scs: list[ScenarioData],
    opt: IdentifyOptions,
    say: Say,
    truth: GeneratorParameters | None,
) -> None:
    say("validation: playing in the held-out scenarios")
    model = res.complete()
    if model is None:
        res.problems.append("validation skipped: the identified set is incomplete or not physically valid")
        return
    res.validation, res.validation_truth = validation.validate(scs, model, truth, opt.f_nominal_hz)
    res.problems.extend(res.validation.problems)
    _withhold_failed_model(res)


def _withhold_failed_model(res: IdentificationResult) -> None:
    """A model that fails MOD-026 against the measurement on every validation event is not
    published as identified, however small its standard deviations: its structure lacks
    something the machine does (saturation put X_d +42 % as identified while every event's Q
    missed by 0.34-0.91 pu), and the diagnosis is the way on."""
    measured = res.validation_truth if res.validation_truth is not None else res.validation
    if measured is None or not measured.scenarios or any(s.mod026_pass for s in measured.scenarios):
        return
    dp = [s.max_dp for s in measured.scenarios]
    dq = [s.max_dq for s in measured.scenarios]
    why = (
        f"the identified model fails MOD-026 (|ΔP|, |ΔQ| ≤ {validation.MOD026_TOLERANCE_PU:g} pu) on every validation "
        f"event ({len(dp)}; max |ΔP| {min(dp):.3f}-{max(dp):.3f}, |ΔQ| {min(dq):.3f}-{max(dq):.3f} pu): the model "
        "structure is insufficient, run phid diagnose"
    )
    res.problems.append(why)
    for est in res.estimates.values():
        est.disqualify("withheld: the model fails MOD-026 on every validation event")
