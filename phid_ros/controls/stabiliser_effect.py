"""A stabiliser identified from its effect, where its output was not recorded.

A recorder that keeps V_t, P, Q and E_fd but not the stabiliser's own output still shows it: in a
test the sheet says the stabiliser was on for (``regulator: avr+pss`` in the map or manifest), the
regulator's error carried V_S, and E_fd answered it. The exciter is fitted on the tests without
it (the stabiliser off, or at no load, where P_e does not move and V_S with it); held there, each
stabiliser model's constants are fitted so that the exciter, driven by V_t *and* the stabiliser's
answer to the recorded P_e (and speed, where a dual-input model reads it), reproduces the PSS-on
test's E_fd, through the exciter's limits. The stabiliser is named only where it explains clearly
more of E_fd than the exciter alone does (``NAMED_BELOW``, the rule every kind is named by).

What this cannot tell apart is said by the same checks as any fit's: a constant is given as
determined only where a second start and a profile agree (:func:`fit_model`). A stabiliser acts
through the exciter's whole path, so its gain and the exciter's are known together: the exciter's
constants come from the other tests, which is why those tests are needed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from phid_ros.controls.cases import KINDS, ControlCase, acted_unrecorded, control_case, rmse
from phid_ros.controls.choice import NAMED_BELOW, judged, simplest_best
from phid_ros.controls.fit import ControlFit, fit_model
from phid_ros.controls.models import MODELS, ControlInputs, ControlModel, LimitsError, OperatingLevels, of_kind
from phid_ros.controls.play import limited_output, open_limits
from phid_ros.ident.scenario import ScenarioData


def exciter_values(exciter: ControlFit) -> dict[str, float]:
    """The exciter's constants as a fit gave them, complete: a limit never reached is open."""
    model = MODELS[exciter.model]
    given = {k: float(v) for k, v in exciter.parameters.items() if v is not None}
    return model.completed({**model.defaults(), **open_limits(model), **given})


def through_exciter(
    stabiliser: type[ControlModel], exciter: type[ControlModel], held: Mapping[str, float]
) -> type[ControlModel]:
    """``stabiliser`` seen through ``exciter`` held at ``held``: its constants, E_fd its output."""

    class Through(stabiliser):  # type: ignore[valid-type,misc]
        @classmethod
        def _with_v_s(cls, values: Mapping[str, float], x: ControlInputs) -> ControlInputs:
            own = super().response(values, x, 0.0)  # the stabiliser's answer to P_e (and speed)
            return replace(x, v_s=own if x.v_s is None else x.v_s + own)

        @classmethod
        def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> np.ndarray:
            return exciter.response(held, cls._with_v_s(values, x), reference)

        @classmethod
        def limited(
            cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
        ) -> np.ndarray | None:
            return exciter.limited(held, cls._with_v_s(values, x), reference, levels)

    Through.__name__ = Through.__qualname__ = f"{stabiliser.name}Through{exciter.name}"
    return Through


def _exciter_alone(exciter: type[ControlModel], held: Mapping[str, float], cases: Sequence[ControlCase]) -> float:
    """The exciter's own error on the cases (its limits, each stepped case's reference fitted): what
    a stabiliser must explain clearly more of to be named."""
    played = [limited_output(exciter, held, c)[0] for c in cases]
    return rmse(cases, played)


def stabiliser_from_effect(
    scenarios: Sequence[ScenarioData],
    exciter: ControlFit | str | None,
    candidates: Sequence[str] | None = None,
) -> ControlFit | str | None:
    """The stabiliser fitted through the held exciter on the tests whose stabiliser acted unrecorded;
    None where there is none such (the caller says why nothing is identified), else the fit or why
    not."""
    # the tests an exciter is fitted on (a fault's switching would weigh in every constant)
    on = [
        s for s in scenarios if acted_unrecorded(s) and s.kind in KINDS["exciter"].fitted and s.has("p_e", "v_t", "v_f")
    ]
    if not on:
        return None
    names = ", ".join(sorted({s.name for s in on}))
    if not isinstance(exciter, ControlFit) or not exciter.named:
        return (
            f"not identified: its output is not recorded and the exciter, through which its effect on E_fd "
            f"shows ({names}), is not named from the tests without it"
        )
    model = MODELS[exciter.model]
    held = exciter_values(exciter)
    fit = [c for c in (control_case(s, "exciter") for s in on if s.role == "identify") if c is not None]
    check = [c for c in (control_case(s, "exciter") for s in on if s.role == "validate") if c is not None]
    if not fit:
        return f"not identified: no identification scenario among the tests it acted in ({names})"
    try:
        if model.limited(held, fit[0].inputs, 0.0, fit[0].levels) is None:  # type: ignore[arg-type]
            return f"not identified: the exciter {model.name} simulates no limits to play its effect through"
        return _fitted_through(model, held, fit, check, on, names, candidates)
    except LimitsError as exc:  # the exciter's fitted limits cannot hold a PSS-on test's operating point
        return f"not identified: the exciter {model.name} as fitted cannot play {names}: {exc}"


def _fitted_through(
    model: type[ControlModel],
    held: Mapping[str, float],
    fit: Sequence[ControlCase],
    check: Sequence[ControlCase],
    on: Sequence[ScenarioData],
    names: str,
    candidates: Sequence[str] | None,
) -> ControlFit | str:
    """Each readable stabiliser model fitted through the held exciter; the simplest best, named
    where it explains clearly more of E_fd than the exciter alone."""
    judge = check or fit
    alone = _exciter_alone(model, held, judge)
    readable = [
        m
        for m in of_kind("stabiliser")
        if (candidates is None or m.name in candidates) and all(s.has(*m.needs) for s in on)
    ]
    if not readable:
        return f"not identified: no stabiliser model among the candidates reads what {names} recorded"
    fits: list[ControlFit] = []
    for m in readable:
        through = through_exciter(m, model, held)
        f = fit_model(through, fit, check, checked=True, played_through_limits=True)
        f.model, f.kind = m.name, "stabiliser"
        # the stabiliser's output limits were never reached in a play-in that does not see them
        for p in m.parameters:
            if p.limit:
                f.parameters[p.name], f.uncertainty[p.name], f.identifiable[p.name] = None, None, False
        fits.append(f)
    best, alike = simplest_best(fits)
    err = judged(best)
    best.none_heldout_rmse = alone
    best.named = bool(math.isfinite(err) and err < NAMED_BELOW * alone)
    if not best.named:
        best.identifiable = dict.fromkeys(best.identifiable, False)
    best.alternatives = {f.model: judged(f) for f in alike}
    where = "held-out" if best.heldout_rmse is not None else "fit (no validation scenarios)"
    best.why = (
        f"{best.model}: from its effect on E_fd ({names}: its output not recorded) through the exciter "
        f"{model.name} fitted on the tests without it; {where} error of E_fd {err:.4g} pu against "
        f"{alone:.4g} pu with the exciter alone"
        + ("" if best.named else f" (named below {NAMED_BELOW:g} of it: the recordings do not show the stabiliser)")
    )
    return best
