"""The limits a control system reached in the recordings, fitted.

A model's output limits (SEXS's EMAX, ESST5B's VRMAX) are ``null`` unless the recorded output
reached them. Reached means a flat top: the recorded output sits within a few noise levels of its
extreme for at least ``MIN_FLAT_S``, having arrived there at speed or with the small-signal fit
wanting it further. Then the limit is fitted from there, the model played through its limits
(:meth:`ControlModel.limited`), every stepped scenario's reference a constant of that fit (the
response is no longer linear in it), and the faults join the exciter's fit: a fault drives the
field voltage to its ceiling, which is what pins it. A limit that fit leaves where it never binds
is dropped with it. Without a limit reached, faults stay out of the exciter's fit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.controls.cases import ControlCase, output_noise, rmse
from phid_ros.controls.fit import ControlFit, Limits, fit_model, known_values
from phid_ros.controls.models import MODELS, ControlModel, LimitsError
from phid_ros.controls.play import limited_output, open_limits, simulate_cases, simulate_references

Array = NDArray[np.float64]

MIN_FLAT_S = 0.012  # a recorded output on a limit: flat at its extreme at least this long


FLAT_NOISES = 6.0  # "flat": within this many output noises of the extreme (found on a 3-sample mean)


WANTED_NOISES = 5.0  # ... while the small-signal fit wants it this many noises further


LIMIT_RANGE = 0.10  # a reached limit is fitted within this share of the extreme it was found at


# an input limit is looked for from this share of the error's largest swing beyond rest outwards
INPUT_LIMIT_FLOOR = 0.05


# ... and kept where the step tests' error falls by this share at least with it (a freed limit
# can always be put out of reach, so any fit is at least as good with it)
INPUT_LIMIT_GAIN = 0.2


def reached_limits(
    model: ControlModel, values: Mapping[str, float], cases: Sequence[ControlCase], noise: float
) -> Limits:
    """The output limits the recordings reached (see the module's note), each with where its fit
    starts and its range: the recorded extreme it sat at, in the limit's own terms.

    Found: a limit hit at speed (a fault drives E_fd to its ceiling within tens of ms) or one the
    small-signal fit wants past. Not found: a limit crept up to (E_fd sliding to its floor over
    a second through a long lead-lag) that the small-signal fit, bent by that very case, does
    not want past; the fit's constants are then flagged as the profile finds them, not freed.
    Never inside what any case's output reached: behind ANDES's EXST1 input limit E_fd rose to
    5.01 in a V_ref step, and SEXS's E_MAX, freed down to 4.3, sat at 4.59 to mimic that limit."""
    if model.output_limits is None or not any(c.levels is not None for c in cases):
        return {}
    lower, upper = model.output_limits
    found: dict[str, float] = {}
    rest: dict[str, float] = {}  # the limit's value at each case's operating point: it must hold them all
    reached: dict[str, float] = {}  # the outermost the output went, in the limit's terms
    pred = simulate_cases(model, {**model.defaults(), **values}, cases)
    for c, want in zip(cases, pred):
        if c.levels is None or c.output.size < 3:
            continue
        for sign, name in ((1.0, upper), (-1.0, lower)):
            at_rest = model.limit_at(name, c.levels.output0, c.levels, 0)
            rest[name] = at_rest if name not in rest else sign * max(sign * rest[name], sign * at_rest)
        flat_n = max(3, int(math.ceil(MIN_FLAT_S / c.inputs.dt)))
        span = float(np.ptp(c.output))
        tol = max(FLAT_NOISES * noise, 0.002 * span)
        for sign, name in ((1.0, upper), (-1.0, lower)):
            y = sign * c.output
            # the top found on the output averaged over the flat span: a lone noise peak is no top
            top = np.convolve(y, np.ones(flat_n) / flat_n, mode="same")
            k = int(np.argmax(top[flat_n:-flat_n])) + flat_n if len(y) > 3 * flat_n else int(np.argmax(top))
            level = float(top[k])
            # a limit is never inside what the output reached (less its noise), wherever it did
            beyond = model.limit_at(name, c.levels.output0 + sign * (level - tol), c.levels, k)
            if name not in reached or sign * beyond > sign * reached[name]:
                reached[name] = beyond
            on = top >= level - tol
            # the run of flat samples around the extreme
            a = k
            while a > 0 and on[a - 1]:
                a -= 1
            b = k
            while b + 1 < len(y) and on[b + 1]:
                b += 1
            if b - a + 1 < flat_n:
                continue
            # a limit is hit: the output arrives at speed and stops dead (a settling output creeps
            # up to its plateau); or the fit wants it further. Either: a limit, not a plateau
            hit = a >= 2 and float(level - top[a - 2]) > 3.0 * tol
            wanted = float(np.mean(sign * want[a : b + 1])) >= level + WANTED_NOISES * max(noise, 1e-9)
            if not (hit or wanted):
                continue
            at = model.limit_at(name, c.levels.output0 + sign * level, c.levels, k)
            # the limit is one value: the outermost flat top found (a case that sat lower was
            # held there by something else)
            if name not in found or sign * at > sign * found[name]:
                found[name] = at
    out: Limits = {}
    for name, at in found.items():
        sign = 1.0 if name == upper else -1.0
        # the range in terms of the limit's size or its distance from rest (a floor at 0 pu)
        scale = max(abs(at), abs(at - rest[name]))
        near, far = at - sign * LIMIT_RANGE * scale, at + sign * LIMIT_RANGE * scale
        # never inside an operating point a case rested at (the limit held it), by a margin
        margin = 0.01 * scale
        near = sign * max(sign * near, sign * rest[name] + margin, sign * reached[name])
        if sign * far <= sign * near:
            continue
        lo, hi = sorted((near, far))
        out[name] = (min(max(at, lo), hi), lo, hi)
    return out


def limits_seen(model: ControlModel, cases: Sequence[ControlCase], reached: Mapping[str, Any]) -> dict[str, float]:
    """Each output limit not ``reached``: the outermost value the recorded output implies, in the
    limit's terms (a static exciter's E_fd of 4.8 at V_T 0.19 in a fault: V_RMAX at least 25). A
    record that writes a limit below it would cut what was recorded."""
    if model.output_limits is None:
        return {}
    lower, upper = model.output_limits
    out: dict[str, float] = {}
    for c in cases:
        if c.levels is None or not c.output.size:
            continue
        y = c.levels.output0 + c.output
        for sign, name in ((1.0, upper), (-1.0, lower)):
            if name in reached:
                continue
            at = max(sign * model.limit_at(name, float(y[k]), c.levels, k) for k in range(len(y)))
            out[name] = sign * max(at, sign * out[name]) if name in out else sign * at
    return out


def wanted_input_limits(model: ControlModel, values: Mapping[str, float], cases: Sequence[ControlCase]) -> Limits:
    """Where a fit may put the model's input limits (its error's VIMIN, VIMAX): between the error at
    rest and the largest the small-signal model drives it to in the recordings, either way. No
    flat top shows an input limit (behind a lead-lag the output keeps moving), so these are
    candidates: the fit that frees them is kept only where it binds and explains clearly more
    (see :func:`with_reached_limits`)."""
    if model.input_limits is None or not any(c.levels is not None for c in cases):
        return {}
    full = model.completed({**model.defaults(), **values})
    refs = simulate_references(model, full, cases)
    highest, lowest, rest_hi, rest_lo = -math.inf, math.inf, -math.inf, math.inf
    for c, r in zip(cases, refs):
        if c.levels is None:
            continue
        try:
            e = model.input_signal(full, c.inputs, r, c.levels)
        except LimitsError:
            continue
        if e is None or not e.size:
            continue
        highest, lowest = max(highest, float(np.max(e))), min(lowest, float(np.min(e)))
        rest_hi, rest_lo = max(rest_hi, float(e[0])), min(rest_lo, float(e[0]))
    if not math.isfinite(highest):
        return {}
    lower, upper = model.input_limits
    out: Limits = {}
    # the swing beyond rest on each side; a limit is looked for within it, never inside the rest
    for name, far, rest, sign in ((upper, highest, rest_hi, 1.0), (lower, lowest, rest_lo, -1.0)):
        swing = sign * (far - rest)
        if swing <= 0:
            continue
        near = rest + sign * INPUT_LIMIT_FLOOR * swing
        lo, hi = sorted((near, far))
        out[name] = (rest + sign * 0.5 * swing, lo, hi)
    return out


def _binding(
    model: ControlModel, limited: ControlFit, cases: Sequence[ControlCase], noise: float
) -> tuple[list[Array], list[str]]:
    """The cases played through ``limited``'s limits, and the limits it freed that never bind
    there (moved out of reach, no case's output moves by more than the noise)."""
    values = model.completed({**model.defaults(), **open_limits(model), **known_values(limited)})
    refs = limited.references
    played = [limited_output(model, values, c, refs.get(c.name, 0.0))[0] for c in cases]
    uppers = {p[1] for p in (model.output_limits, model.input_limits) if p is not None}
    idle = []
    for name in limited.limits:
        # a limit out of reach; a loading factor where it vanishes
        far = {**values, name: 1e9 if name in uppers else 0.0 if name == model.loading else -1e9}
        free = [limited_output(model, far, c, refs.get(c.name, 0.0))[0] for c in cases]
        with np.errstate(invalid="ignore"):  # a play that diverged without the limit: the limit acts
            moved = max(float(np.max(np.abs(a - b))) for a, b in zip(played, free))
        if moved < WANTED_NOISES * max(noise, 1e-9):  # NaN: not idle
            idle.append(name)
    return played, idle


def with_reached_limits(
    model: ControlModel,
    small_signal: ControlFit,
    fit: Sequence[ControlCase],
    faults: Sequence[ControlCase],
    held: Sequence[ControlCase],
) -> ControlFit:
    """``small_signal`` refitted with the output limits the recordings reached, the faults joining
    the fit; as it was where none is reached (or the limits found cannot hold a case's operating
    point). Then, for a model with input limits, refitted with those freed too, kept where they
    bind and the step tests' error falls by ``INPUT_LIMIT_GAIN`` at least."""
    cases = [*fit, *faults]
    noise = output_noise(fit)
    outcome = small_signal
    limits = reached_limits(model, known_values(small_signal), cases, noise)
    if limits:
        if model.loading is not None and model.output_limits and model.output_limits[1] in limits:
            # a ceiling lowered by the field current (K_C I_FD): freed with it, so tops reached at
            # different field currents are one ceiling (Mostar's no-load and on-line steps sat 4 %
            # apart in V_T terms; the published ST5B has K_C 0.98)
            q = next(p for p in model.parameters if p.name == model.loading)
            limits = {**limits, q.name: (0.5 * (q.low + q.high), q.low, q.high)}
        try:
            limited = fit_model(model, cases, held, checked=False, start_at=known_values(small_signal), limits=limits)
            played, idle = _binding(model, limited, cases, noise)
            if idle == [model.loading]:  # the loading does not show: the ceiling alone
                limits = {k: v for k, v in limits.items() if k != model.loading}
                limited = fit_model(model, cases, held, checked=False, start_at=known_values(limited), limits=limits)
                played, idle = _binding(model, limited, cases, noise)
        except LimitsError:
            limited, idle = small_signal, []
        # a limit the fit put where it never binds was no limit (a fast step onto a flat plateau
        # looks like one): its value would carry no information, and its std none either
        if limited is not small_signal and not idle:
            # judged on the cases the other models' fits are (the step tests), not on the faults too
            limited.fit_rmse = rmse(fit, played[: len(fit)])
            outcome = limited
    # the input limits freed from the small-signal fit alone and beside the output limits found:
    # an input limit flattens E_fd's rise behind a slow lag, which reads as a flat top, so each
    # start may fall into the other's local minimum (EXST1 from SEXS's fit put VIMIN at rest)
    trials = [
        _with_input_limits(model, base, fit, faults, held, noise)
        for base in ((small_signal, outcome) if outcome is not small_signal else (small_signal,))
    ]
    freed = min((f for f in trials if f is not None), key=lambda f: f.fit_rmse, default=None)
    if freed is None or freed.fit_rmse > (1.0 - INPUT_LIMIT_GAIN) * outcome.fit_rmse:
        return outcome
    return freed


def _with_input_limits(
    model: ControlModel,
    base: ControlFit,
    fit: Sequence[ControlCase],
    faults: Sequence[ControlCase],
    held: Sequence[ControlCase],
    noise: float,
) -> ControlFit | None:
    """``base`` refitted with its input limits freed one side at a time, the side the error
    swings furthest past rest first, the faults joining the fit; a further side kept only where
    the step tests' error falls by ``INPUT_LIMIT_GAIN`` with it (both freed at once, a side the
    error barely passed put VIMIN at rest and sent K_A from 238 to 22). None where no input
    limit binds. ``fit_rmse`` on the step tests."""
    cases = [*fit, *faults]
    wanted = wanted_input_limits(model, known_values(base), cases)
    current: ControlFit | None = None
    for name in sorted(wanted, key=lambda n: wanted[n][1] - wanted[n][2]):
        start = current or base
        try:
            freed = _freed(model, start, {**start.limits, name: wanted[name]}, name, cases, held, noise)
        except LimitsError:
            continue
        if freed is None:
            continue
        freed.fit_rmse = rmse(fit, _binding(model, freed, cases, noise)[0][: len(fit)])
        if current is None or freed.fit_rmse <= (1.0 - INPUT_LIMIT_GAIN) * current.fit_rmse:
            current = freed
    return current


def _freed(
    model: ControlModel,
    start: ControlFit,
    trial: Limits,
    name: str,
    cases: Sequence[ControlCase],
    held: Sequence[ControlCase],
    noise: float,
) -> ControlFit | None:
    """``start`` refitted with the limits ``trial`` free; the ones that never bind dropped and the
    rest refitted, None where ``name`` (the side being tried) does not bind."""
    uppers = {p[1] for p in (model.output_limits, model.input_limits) if p is not None}
    freed = fit_model(model, cases, held, checked=False, start_at=known_values(start), limits=trial)
    idle = _binding(model, freed, cases, noise)[1]
    # an output limit the fit now pushes to the far end of its range was a top the input limit
    # flattened (behind a slow lag E_fd barely rises): no limit of its own
    idle += [
        n
        for n in start.limits
        if n not in idle
        and n not in (model.input_limits or ())
        and math.isclose(freed.parameters[n] or 0.0, trial[n][2 if n in uppers else 1], rel_tol=1e-4)
    ]
    if name in idle:
        return None
    if idle:
        trial = {k: v for k, v in trial.items() if k not in idle}
        freed = fit_model(model, cases, held, checked=False, start_at=known_values(freed), limits=trial)
        if _binding(model, freed, cases, noise)[1]:
            return None
    return freed


def on_step_tests(
    model: ControlModel, limited: ControlFit, fit: Sequence[ControlCase], held: Sequence[ControlCase]
) -> ControlFit:
    """A fit that found limits, its small-signal constants refitted on the step tests alone with
    the output limits held (the input limits free): how the named model's constants are given,
    so the models compete on it. Judged on the fit with the faults instead, STEPS's own SEXS erred
    0.0158 pu held out against IEEET1's 0.0085 (no limit, no fault) and lost to it; refitted, 0.0084."""
    if not limited.limits:
        return limited
    try:
        refit = refit_through_limits(model, limited, fit, held, checked=False)
    except LimitsError:
        return limited
    return with_limits_of(refit, limited)


def with_limits_of(refit: ControlFit, limited: ControlFit) -> ControlFit:
    """``refit`` (the small-signal constants refitted through ``limited``'s limits) given
    ``limited``'s output limits as that fit found them, with their verdicts."""
    for n in limit_values(limited):
        refit.parameters[n], refit.uncertainty[n] = limited.parameters[n], limited.uncertainty[n]
        refit.identifiable[n] = limited.identifiable[n]
    refit.limits = limited.limits
    refit.pressed = sorted({*refit.pressed, *(n for n in limited.pressed if n in limit_values(limited))})
    return refit


def refit_through_limits(
    model: ControlModel,
    f: ControlFit,
    fit: Sequence[ControlCase],
    held: Sequence[ControlCase],
    *,
    checked: bool,
) -> ControlFit:
    """``model`` fitted on ``fit`` from ``f``'s constants, played through the limits ``f`` found:
    its output limits held, its input limits fitted again."""
    return fit_model(
        model,
        fit,
        held,
        checked=checked,
        start_at=known_values(f),
        limits=input_limits_of(f),
        held_limits=limit_values(f),
    )


def limit_values(f: ControlFit) -> dict[str, float]:
    """The values of the output limits ``f`` freed (found reached): held while the small-signal
    constants are fitted on the step tests, which a fault's ceiling is not seen in."""
    inputs = MODELS[f.model].input_limits or ()
    return {n: float(v) for n in f.limits if n not in inputs and (v := f.parameters.get(n)) is not None}


def input_limits_of(f: ControlFit) -> Limits:
    """The input limits ``f`` freed, from its values within their search ranges: fitted again with
    the small-signal constants, since a step test reaches them too (a V_ref step of 0.15 an input
    limit of 0.1) and, held at a fault's value, the step tests' constants bend around them."""
    inputs = MODELS[f.model].input_limits or ()
    return {n: (float(v), *f.limits[n][1:]) for n in f.limits if n in inputs and (v := f.parameters.get(n)) is not None}
