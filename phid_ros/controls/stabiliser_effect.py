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

from phid_ros.controls.cases import KINDS, ControlCase, acted_unrecorded, control_case, rmse
from phid_ros.controls.choice import NAMED_BELOW, judged, simplest_best
from phid_ros.controls.fit import ControlFit, fit_model
from phid_ros.controls.models import (
    MODEL_DATA,
    MODELS,
    Array,
    ControlInputs,
    ControlModel,
    LimitsError,
    OperatingLevels,
    of_kind,
)
from phid_ros.controls.play import limited_output, open_limits
from phid_ros.ident.scenario import ScenarioData


def exciter_values(exciter: ControlFit) -> dict[str, float]:
    """The exciter's constants as a fit gave them, complete: a limit never reached is open."""
    model = MODELS[exciter.model]
    given = {k: float(v) for k, v in exciter.parameters.items() if v is not None}
    return model.completed({**model.defaults(), **open_limits(model), **given})


class ThroughExciter(ControlModel):
    """A stabiliser seen through an exciter held at its fitted constants: the stabiliser's
    constants, data and checks, E_fd its output (the stabiliser's answer to P_e, and speed, added
    to the exciter's V_S). The fit takes it as any model; only the output is the exciter's."""

    def __init__(self, stabiliser: ControlModel, exciter: ControlModel, held: Mapping[str, float]) -> None:
        self.stabiliser, self.exciter, self.held = stabiliser, exciter, dict(held)
        for name in MODEL_DATA:
            setattr(self, name, getattr(stabiliser, name))

    def __repr__(self) -> str:
        return f"ThroughExciter({self.stabiliser!r}, {self.exciter!r})"

    def start(self, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        return self.stabiliser.start(earlier)

    def completed(self, values: Mapping[str, float]) -> dict[str, float]:
        return self.stabiliser.completed(values)

    def record_problem(self, values: Mapping[str, float]) -> str | None:
        return self.stabiliser.record_problem(values)

    def recorded(self, values: Mapping[str, float]) -> dict[str, float]:
        return self.stabiliser.recorded(values)

    def not_simulated(self, values: Mapping[str, float]) -> list[str]:
        return self.stabiliser.not_simulated(values)

    def limit_at(self, name: str, output: float, levels: OperatingLevels, k: int) -> float:
        return self.stabiliser.limit_at(name, output, levels, k)

    def _with_v_s(self, values: Mapping[str, float], x: ControlInputs) -> ControlInputs:
        own = self.stabiliser.response(values, x, 0.0)
        return replace(x, v_s=own if x.v_s is None else x.v_s + own)

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        return self.exciter.response(self.held, self._with_v_s(values, x), reference)

    def limited(
        self, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        return self.exciter.limited(self.held, self._with_v_s(values, x), reference, levels)


def _exciter_alone(exciter: ControlModel, held: Mapping[str, float], cases: Sequence[ControlCase]) -> float:
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
    model: ControlModel,
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
        through = ThroughExciter(m, model, held)
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
