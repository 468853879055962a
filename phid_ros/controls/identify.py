"""The exciter, the governor and the stabiliser identified from the recordings, as MOD-026/027
ask for them: per kind its cases (:mod:`~phid_ros.controls.cases`), every registered model of the
kind fitted (:mod:`~phid_ros.controls.fit`, with the limits reached:
:mod:`~phid_ros.controls.limits`) and one named or none (:mod:`~phid_ros.controls.choice`). A kind
without a case to fit may have another route (:data:`WITHOUT_CASES`: a stabiliser from its effect
on E_fd)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from phid_ros.controls.cases import KINDS, ControlCase, cases_of, no_control, output_noise, rmse
from phid_ros.controls.choice import NAMED_BELOW, SIMPLEST_WITHIN, judged, simplest_best, without_unseen_terms
from phid_ros.controls.fit import ControlFit, fit_model, known_values
from phid_ros.controls.limits import (
    limits_seen,
    on_step_tests,
    refit_through_limits,
    with_limits_of,
    with_reached_limits,
)
from phid_ros.controls.models import MODELS, of_kind
from phid_ros.controls.stabiliser_effect import stabiliser_from_effect
from phid_ros.ident.field_base import on_machine_field_base
from phid_ros.ident.scenario import ScenarioData


def controls_json(found: dict[str, ControlFit | str]) -> dict[str, Any]:
    """identify's JSON ``controls``: per kind the fit, or ``{"model": null, "why": ...}``."""
    return {k: f.as_json() if isinstance(f, ControlFit) else {"model": None, "why": f} for k, f in found.items()}


def identify_machine_controls(
    scenarios: Sequence[ScenarioData],
    route_details: Mapping[str, Any],
    saturation: tuple[float, float] | None,
    candidates: Mapping[str, Sequence[str]] | None = None,
    starts: Mapping[str, Mapping[str, float]] | None = None,
    kinds: Sequence[str] | None = None,
) -> tuple[list[ScenarioData], dict[str, ControlFit | str], list[str]]:
    """The control systems of a machine just identified (its ``route_details``), as ``phid
    identify`` and the monitor's recalibration both fit them: E_fd put on the machine's base
    (:func:`on_machine_field_base`), then :func:`identify_controls`; an exciter is not fitted from
    field channels that gave the machine an impossible value
    (:func:`phid_ros.ident.determinable.impossible_field`). Returns (the scenarios with E_fd on the
    machine's base, the fits, notes for the user)."""
    from phid_ros.controls.models import KINDS_IN_ORDER
    from phid_ros.ident.determinable import impossible_field

    on_base, base_note = on_machine_field_base(scenarios, saturation)
    notes = [base_note] if base_note else []
    distrust = impossible_field(route_details)
    wanted = [k for k in (kinds or KINDS_IN_ORDER) if not (distrust and k == "exciter")]
    found = identify_controls(on_base, candidates, starts, wanted)
    if distrust and "exciter" in (kinds or KINDS_IN_ORDER):
        found = {"exciter": f"not identified: {distrust}", **found}
        notes.append(f"the exciter is not identified: {distrust}")
    return on_base, found, notes


def _stabiliser_from_effect(
    scenarios: Sequence[ScenarioData], found: Mapping[str, ControlFit | str], allowed: Sequence[str] | None
) -> ControlFit | str | None:
    return stabiliser_from_effect(scenarios, found.get("exciter"), allowed)


# a kind's route where no scenario records what its fit needs: (scenarios, the kinds found so
# far, the candidate models or None) -> its fit or why none, None where the route does not apply
OtherRoute = Callable[
    [Sequence[ScenarioData], Mapping[str, ControlFit | str], Sequence[str] | None], ControlFit | str | None
]
WITHOUT_CASES: dict[str, OtherRoute] = {
    "stabiliser": _stabiliser_from_effect,
}


def identify_controls(
    scenarios: Sequence[ScenarioData],
    candidates: Mapping[str, Sequence[str]] | None = None,
    starts: Mapping[str, Mapping[str, float]] | None = None,
    kinds: Sequence[str] | None = None,
) -> dict[str, ControlFit | str]:
    """For each kind (exciter, governor, stabiliser): the named model's fit, or why none is named.

    ``candidates`` restricts a kind to the models named (a plant engineer who knows the unit's
    exciter is static says EXST1); the default is every registered model of the kind.
    ``starts``: per kind, constants of a model the user has (an existing .dyr's), where the fit
    of the model they belong to starts. ``kinds``: only these (default every kind)."""
    out: dict[str, ControlFit | str] = {}
    for kind in KINDS if kinds is None else [k for k in KINDS if k in kinds]:
        allowed = (candidates or {}).get(kind)
        fit, held = cases_of(scenarios, kind, "identify"), cases_of(scenarios, kind, "validate")
        if not fit:
            route = WITHOUT_CASES.get(kind)
            other = route(scenarios, out, allowed) if route is not None else None
            out[kind] = (
                other
                if other is not None
                else f"not identified: no scenario with {' and '.join(KINDS[kind].needs)} to fit"
            )
            continue
        # a fault drives the field voltage to its ceiling: fitted only where a limit is (controls.limits)
        faults = cases_of(scenarios, kind, "identify", ("fault",)) if kind == "exciter" else []
        fitted_on = [s for s in scenarios if s.role == "identify"]
        out[kind] = _identified(kind, fitted_on, (fit, faults, held), allowed, (starts or {}).get(kind))
    return out


def _identified(
    kind: str,
    fitted_on: Sequence[ScenarioData],
    cases: tuple[Sequence[ControlCase], Sequence[ControlCase], Sequence[ControlCase]],
    allowed: Sequence[str] | None,
    given: Mapping[str, float] | None,
) -> ControlFit | str:
    """One kind's named fit, or why none is named: ``cases`` are (fitted, faults, held out)."""
    fit, faults, held = cases
    judge = held or fit  # without validation scenarios the fit's own error decides
    none = rmse(judge, no_control(judge))
    noise = output_noise(judge)
    if NAMED_BELOW * none <= noise:
        # no model errs less than the output's own noise: none can be named, none is fitted
        return (
            f"not named: beyond its reference steps the {KINDS[kind].output} moves {none:.4g} pu rms, within "
            f"{1 / NAMED_BELOW:.3g} x its noise ({noise:.4g} pu): the recordings do not show the {kind}"
        )
    models = [m for m in of_kind(kind) if allowed is None or m.name in allowed]
    # a model that reads a channel some identification scenario lacks cannot be fitted there
    # (PSS2A without the rotor speed): the others compete
    unreadable = [m.name for m in models if not all(s.has(*m.needs) for s in fitted_on)]
    models = [m for m in models if m.name not in unreadable]
    if not models:
        lacking = f" ({', '.join(unreadable)} need channels not recorded)" if unreadable else ""
        return f"not identified: no {kind} model among the candidates {sorted(allowed or [])}{lacking}"
    fits: list[ControlFit] = []
    for m in models:  # in registration order: a model may start where a simpler one ended
        earlier = {f.model: known_values(f) for f in fits}
        own = dict(given) if given and set(given) >= {p.name for p in m.fitted()} else None
        limited = with_reached_limits(
            m, fit_model(m, fit, held, earlier, checked=False, start_at=own), fit, faults, held
        )
        fits.append(on_step_tests(m, limited, fit, held))
    chosen, alike = simplest_best(fits)
    if judged(chosen) < NAMED_BELOW * none:
        # the limits as the fit with the faults found them; the small-signal constants fitted
        # and checked on the small-signal tests, played through those limits (a fault's
        # switching, which the smoothed inputs blur, would weigh in every constant's profile)
        model = without_unseen_terms(MODELS[chosen.model], chosen, fit, held)
        best = with_limits_of(refit_through_limits(model, chosen, fit, held, checked=True), chosen)
    else:  # no model is named: none of its constants is given as determined, and none is checked
        best = chosen
        best.identifiable = dict.fromkeys(best.identifiable, False)
    best.seen = limits_seen(MODELS[best.model], [*fit, *faults, *held], best.limits)
    best.alternatives = {f.model: judged(f) for f in alike}
    best.none_heldout_rmse = none
    best.named = bool(judged(best) < NAMED_BELOW * none)
    best.why = _why(best, kind, alike)
    return best


def _why(best: ControlFit, kind: str, alike: Sequence[ControlFit]) -> str:
    """The choice said: the error against no control action, the models that answer as well, the
    limits pressed on an end of their range."""
    err, none = judged(best), best.none_heldout_rmse
    judged_on = "held-out" if best.heldout_rmse is not None else "fit (no validation scenarios)"
    why = f"{best.model}: {judged_on} error {err:.4g} pu against {none:.4g} pu without control action" + (
        "" if best.named else f" (named below {NAMED_BELOW:g} of it: the recordings do not show the {kind})"
    )
    if best.named and alike:
        why += (
            f"; {', '.join(best.alternatives)} answer the recordings as well (within {SIMPLEST_WITHIN - 1:.0%}):"
            f" the simplest is named; name the unit's own with --{kind} MODEL"
        )
    if best.named and best.pressed:
        # the data push the limit where they say it cannot be: the model lacks what set it (a
        # constant ceiling asked to be both a no-load step's top and a loaded step's, which a
        # V_T- and I_FD-dependent one is); said, with the alike models that keep theirs inside
        inside = [f.model for f in alike if not f.pressed]
        why += f"; its {', '.join(best.pressed)} pressed on an end of its range (flagged)" + (
            f"; inside in {', '.join(inside)}" if inside else ""
        )
    return why
