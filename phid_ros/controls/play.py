"""A control model played on its cases: small-signal, with each reference step sized by least
squares, or through its limits (:meth:`ControlModel.limited`), where the response is not linear
in the step."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from phid_ros.controls.cases import ControlCase
from phid_ros.controls.models import ControlModel, LimitsError

Array = NDArray[np.float64]

REFERENCE_SEARCH = (-0.5, 0.5)  # pu: a limited model's reference step is sized within this


def _references(cases: Sequence[ControlCase], predicted: Sequence[Array], unit: Sequence[Array]) -> list[float]:
    """Each stepped case's reference size by least squares (the response is linear in it)."""
    out = []
    for c, p, u in zip(cases, predicted, unit):
        if not c.stepped or c.reference is not None:
            out.append(c.known_reference())
            continue
        denom = float(u @ u)
        out.append(float(u @ (c.output - p)) / denom if denom > 0 else 0.0)
    return out


def _sized(
    model: ControlModel, values: dict[str, float], cases: Sequence[ControlCase]
) -> tuple[list[Array], list[Array], list[float]]:
    """Per case the small-signal response without a reference step, the response to a unit one
    (empty where the case has none) and the step's size by least squares (0 unstepped)."""
    free = [model.response(values, c.inputs, 0.0) for c in cases]
    unit = [model.response(values, c.inputs, 1.0) - f if c.stepped else np.zeros(0) for c, f in zip(cases, free)]
    return free, unit, _references(cases, free, unit)


def simulate_references(model: ControlModel, values: dict[str, float], cases: Sequence[ControlCase]) -> list[float]:
    """Each case's reference step as the small-signal model sizes it."""
    return _sized(model, values, cases)[2]


def simulate_cases(model: ControlModel, values: dict[str, float], cases: Sequence[ControlCase]) -> list[Array]:
    """Each case's output with its reference step sized by least squares."""
    free, unit, refs = _sized(model, values, cases)
    return [f + r * u if c.stepped else f for c, f, u, r in zip(cases, free, unit, refs)]


def limited_output(
    model: ControlModel, values: Mapping[str, float], case: ControlCase, reference: float | None = None
) -> tuple[Array, float]:
    """The case's output deviation played through the model's limits, and its reference step:
    ``reference``, or for a stepped case without one the size a bounded search finds (the
    response is not linear in it). Raises LimitsError where the limits cannot hold the case's
    operating point."""
    from scipy.optimize import minimize_scalar

    assert case.levels is not None
    levels = case.levels

    def played(r: float) -> Array:
        out = model.limited(values, case.inputs, r, levels)
        if out is None:
            raise LimitsError(f"{model.name} simulates no limits")
        return out

    if reference is None:
        reference = case.known_reference()
        if case.stepped and case.reference is None:
            reference = float(
                minimize_scalar(
                    lambda r: float(np.sum((played(r) - case.output) ** 2)),
                    bounds=REFERENCE_SEARCH,
                    method="bounded",
                    options={"xatol": 1e-5},
                ).x
            )
    return played(reference), reference


def open_limits(model: ControlModel) -> dict[str, float]:
    """The model's output and input limits out of reach: a limit the recordings did not reach
    does not act in a fit played through the others (its default would: SEXS's E_MAX 5)."""
    out: dict[str, float] = {}
    for pair in (model.output_limits, model.input_limits):
        if pair is not None:
            out |= {pair[0]: -math.inf, pair[1]: math.inf}
    return out
