"""The exciter and the governor identified from the recordings, as MOD-026/027 ask for them.

Each control system is the map from its recorded inputs to its recorded output, in deviations
from the steady state before each event: the exciter from (V_ref - V_t) to E_fd, the governor
from the speed deviation and load-reference steps to P_m. A reference step (a field step, a
torque step) is one unknown size per scenario, fitted with the model. Every registered model of
the kind (:mod:`phid_ros.controls.models`) is fitted to the identification scenarios and judged
on the validation scenarios (held out); the one with the smallest held-out error is named, and
only if it explains clearly more than "no control action" (the output moving only with the
reference steps): the diagnosis's rule against naming what the data do not show.

Why the inputs are smoothed: the exciter's gain (~100) multiplies the PT's noise (0.002 pu)
into 0.2 pu on E_fd, which an output-error fit answers by lowering the gain; V_t and the speed
are low-passed forward and backward at 40 Hz (no lag). At 10 Hz the filter cut into the
exciter's own band: STEPS's SEXS gave T_E 0.0468 s for 0.05 (at 40 Hz 0.0495).

Faults are left out of the exciter's fit: the field voltage goes to its ceiling, a limit.
Limits are reported as not determined unless the recorded output reached them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.controls.models import ControlInputs, ControlModel, of_kind
from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.uncertainty import block_ids, cluster_robust_cov
from phid_ros.numerics import lowpass2

Array = NDArray[np.float64]

INPUT_CUTOFF_HZ = 40.0
KINDS = {
    # kind: (channels it needs, output channel, scenario kinds with a reference step, kinds fitted)
    "exciter": (("v_t", "v_f"), "v_f", ("field_step",), ("voltage_step", "torque_step", "field_step")),
    "governor": (("omega", "p_m"), "p_m", ("torque_step",), ("voltage_step", "torque_step", "field_step", "fault")),
}
NAMED_BELOW = 0.75  # a model is named when its held-out error is below this share of "no control action"
DETERMINED_STD = 0.10  # relative std at most, for a fitted parameter to be given as determined


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
        }


def _smooth(x: Array, dt: float) -> Array:
    """Zero-phase low-pass: the filter run forward, then backward."""
    forward = lowpass2(x, INPUT_CUTOFF_HZ, dt, steady_start=True)
    return lowpass2(forward[::-1], INPUT_CUTOFF_HZ, dt, steady_start=True)[::-1]


@dataclass
class _Case:
    name: str
    inputs: ControlInputs
    output: Array
    stepped: bool  # a reference step of unknown size at the event


def _cases(scenarios: Sequence[ScenarioData], kind: str, role: str) -> list[_Case]:
    needs, out_channel, stepped_kinds, fitted_kinds = KINDS[kind]
    cases = []
    for s in scenarios:
        if s.role != role or s.kind not in fitted_kinds or not s.has(*needs):
            continue
        pre = s.pre_slice()
        dev = {c: np.asarray(s[c], float) - float(np.mean(s[c][pre])) for c in (*needs, "omega", "v_t") if s.has(c)}
        if not all(np.all(np.isfinite(dev[c])) for c in needs):
            continue
        step = (np.arange(s.n) >= s.k_event).astype(float)
        zero = np.zeros(s.n)
        x = ControlInputs(
            s.dt,
            _smooth(dev["v_t"], s.dt) if "v_t" in dev else zero,
            _smooth(dev["omega"], s.dt) if "omega" in dev else zero,
            step,
        )
        cases.append(_Case(s.name, x, dev[out_channel], s.kind in stepped_kinds))
    return cases


def _references(cases: Sequence[_Case], predicted: Sequence[Array], unit: Sequence[Array]) -> list[float]:
    """Each stepped case's reference size by least squares (the response is linear in it)."""
    out = []
    for c, p, u in zip(cases, predicted, unit):
        if not c.stepped:
            out.append(0.0)
            continue
        denom = float(u @ u)
        out.append(float(u @ (c.output - p)) / denom if denom > 0 else 0.0)
    return out


def _simulate(model: type[ControlModel], values: dict[str, float], cases: Sequence[_Case]) -> list[Array]:
    """Each case's output with its reference step sized by least squares."""
    free = [model.response(values, c.inputs, 0.0) for c in cases]
    unit = [model.response(values, c.inputs, 1.0) - f if c.stepped else np.zeros(0) for c, f in zip(cases, free)]
    refs = _references(cases, free, unit)
    return [f + r * u if c.stepped else f for c, f, u, r in zip(cases, free, unit, refs)]


def _no_control(cases: Sequence[_Case]) -> list[Array]:
    """The output held, but for each reference step (its size by least squares)."""
    out = []
    for c in cases:
        u = c.inputs.reference_step
        r = float(u @ c.output) / float(u @ u) if c.stepped else 0.0
        out.append(r * u)
    return out


def _rmse(cases: Sequence[_Case], predicted: Sequence[Array]) -> float:
    err = np.concatenate([c.output - p for c, p in zip(cases, predicted)]) if cases else np.zeros(0)
    return float(np.sqrt(np.mean(err**2))) if err.size else math.nan


def fit_model(model: type[ControlModel], fit: Sequence[_Case], held: Sequence[_Case]) -> ControlFit:
    """``model``'s fitted parameters (log scale, in their ranges; the limits held), their stds
    from the Jacobian, and its error on the held-out cases."""
    from scipy.optimize import least_squares

    free = [p for p in model.fitted() if p.high > p.low]
    values0 = model.defaults()
    log = [p.low > 0 for p in free]

    def values_at(x: Array) -> dict[str, float]:
        v = dict(values0)
        for p, xi, lg in zip(free, x, log):
            v[p.name] = float(np.exp(xi)) if lg else float(xi)
        return v

    def residual(x: Array) -> Array:
        pred = _simulate(model, values_at(x), fit)
        return np.concatenate([c.output - p for c, p in zip(fit, pred)])

    lo = np.array([math.log(p.low) if lg else p.low for p, lg in zip(free, log)])
    hi = np.array([math.log(p.high) if lg else p.high for p, lg in zip(free, log)])
    x0 = np.clip(np.array([math.log(p.default) if lg else p.default for p, lg in zip(free, log)]), lo, hi)
    sol = least_squares(residual, x0, bounds=(lo, hi), x_scale="jac", max_nfev=200)
    values = values_at(sol.x)
    # the residuals of one scenario are correlated (its dynamics, the smoothing): clustered by
    # scenario, not the textbook s^2 (J'J)^-1, which gave T_E 0.0468 +- 0.0001 for a true 0.05
    blocks = block_ids([c.output.size for c in fit], max(c.output.size for c in fit))
    cov = cluster_robust_cov(np.asarray(sol.jac), np.asarray(sol.fun), blocks)
    std_x = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    params: dict[str, float | None] = {}
    std: dict[str, float | None] = {}
    ident: dict[str, bool] = {}
    at_bound = (np.abs(sol.x - lo) < 1e-6) | (np.abs(sol.x - hi) < 1e-6)
    for p, sx, lg, b in zip(free, std_x, log, at_bound):
        v = values[p.name]
        sd = abs(v) * float(sx) if lg else float(sx)
        params[p.name], std[p.name] = v, sd
        ident[p.name] = bool(not b and math.isfinite(sd) and sd <= DETERMINED_STD * max(abs(v), 1e-9))
    for p in model.parameters:
        if p.limit:  # never reached in a linear fit: the data say nothing of it
            params[p.name], std[p.name], ident[p.name] = None, None, False
    pred = _simulate(model, values, fit)
    refs = _references(
        fit,
        [model.response(values, c.inputs, 0.0) for c in fit],
        [model.response(values, c.inputs, 1.0) - model.response(values, c.inputs, 0.0) for c in fit],
    )
    held_rmse = _rmse(held, _simulate(model, values, held)) if held else None
    return ControlFit(
        model.name,
        model.kind,
        params,
        std,
        ident,
        _rmse(fit, pred),
        held_rmse,
        None,
        False,
        "",
        {c.name: r for c, r in zip(fit, refs) if c.stepped},
    )


def controls_json(found: dict[str, ControlFit | str]) -> dict[str, Any]:
    """identify's JSON ``controls``: per kind the fit, or ``{"model": null, "why": ...}``."""
    return {k: f.as_json() if isinstance(f, ControlFit) else {"model": None, "why": f} for k, f in found.items()}


def identify_controls(scenarios: Sequence[ScenarioData]) -> dict[str, ControlFit | str]:
    """For each kind (exciter, governor): the named model's fit, or why none is named."""
    out: dict[str, ControlFit | str] = {}
    for kind in KINDS:
        fit, held = _cases(scenarios, kind, "identify"), _cases(scenarios, kind, "validate")
        if not fit:
            out[kind] = f"not identified: no scenario with {' and '.join(KINDS[kind][0])} to fit"
            continue
        judge = held or fit  # without validation scenarios the fit's own error decides
        none = _rmse(judge, _no_control(judge))
        fits = [fit_model(m, fit, held) for m in of_kind(kind)]
        best = min(fits, key=lambda f: f.heldout_rmse if f.heldout_rmse is not None else f.fit_rmse)
        err = best.heldout_rmse if best.heldout_rmse is not None else best.fit_rmse
        best.none_heldout_rmse = none
        best.named = bool(err < NAMED_BELOW * none)
        best.why = f"{best.model}: held-out error {err:.4g} pu against {none:.4g} pu without control action" + (
            "" if best.named else f" (named below {NAMED_BELOW:g} of it: the recordings do not show the {kind})"
        )
        out[kind] = best
    return out
