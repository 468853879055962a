"""Parameter data of the fourth-order generator model, declared apart from its equations.

Each parameter has one :class:`ParameterSpec` (name used in JSON, messages and
reports; unit; default = Table 1 of the paper; physically plausible range).
:class:`GeneratorParameters` validates a set against the ranges and the
orderings the physics requires (X'_d < X_d, X'_q < X_q, positive time constants).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

from phid_ros.errors import ParameterError
from phid_ros.model.bounds import Bounded


@dataclass(frozen=True)
class ParameterSpec(Bounded):
    name: str
    unit: str
    default: float
    low: float
    high: float
    description: str
    symbol: str  # as printed in tables and figures, in the paper's notation


# Defaults are the PowerFactory machine of Table 1. Ranges bound what a real
# synchronous machine can have; they are validity checks, not search bounds.
PARAMETER_SPECS: tuple[ParameterSpec, ...] = (
    ParameterSpec("H", "s", 3.480, 0.5, 15.0, "inertia constant", "H"),
    ParameterSpec("D", "pu", 0.400, 0.0, 50.0, "damping coefficient", "D"),
    ParameterSpec("X_d", "pu", 2.540, 0.3, 5.0, "d-axis synchronous reactance", "X_d"),
    ParameterSpec("X_q", "pu", 2.410, 0.3, 5.0, "q-axis synchronous reactance", "X_q"),
    ParameterSpec("X_d_prime", "pu", 0.500, 0.05, 1.5, "d-axis transient reactance", "X'_d"),
    ParameterSpec("X_q_prime", "pu", 0.814, 0.05, 2.5, "q-axis transient reactance", "X'_q"),
    ParameterSpec("T_d0_prime", "s", 1.437, 0.05, 20.0, "d-axis open-circuit transient time constant", "T'_d0"),
    ParameterSpec("T_q0_prime", "s", 0.1351, 0.01, 5.0, "q-axis open-circuit transient time constant", "T'_q0"),
)

PARAMETER_NAMES: tuple[str, ...] = tuple(s.name for s in PARAMETER_SPECS)
SPECS_BY_NAME: dict[str, ParameterSpec] = {s.name: s for s in PARAMETER_SPECS}
SYMBOLS: dict[str, str] = {s.name: s.symbol for s in PARAMETER_SPECS}


@dataclass(frozen=True)
class GeneratorParameters:
    """The eight parameters of the fourth-order PH generator model (per unit, seconds)."""

    # defaults: Table 1, as PARAMETER_SPECS declares it (the values are written there only)
    H: float = SPECS_BY_NAME["H"].default
    D: float = SPECS_BY_NAME["D"].default
    X_d: float = SPECS_BY_NAME["X_d"].default
    X_q: float = SPECS_BY_NAME["X_q"].default
    X_d_prime: float = SPECS_BY_NAME["X_d_prime"].default
    X_q_prime: float = SPECS_BY_NAME["X_q_prime"].default
    T_d0_prime: float = SPECS_BY_NAME["T_d0_prime"].default
    T_q0_prime: float = SPECS_BY_NAME["T_q0_prime"].default

    def __post_init__(self) -> None:
        problems = validation_problems(self.as_dict())
        if problems:
            raise ParameterError("invalid generator parameters: " + "; ".join(problems))

    def as_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_mapping(cls, values: Mapping[str, object], *, source: str = "parameters") -> GeneratorParameters:
        """Build from a mapping with exactly the contract names; unknown or missing keys are errors."""
        unknown = sorted(set(values) - set(PARAMETER_NAMES))
        if unknown:
            raise ParameterError(f"{source}: unknown parameter(s) {unknown}; expected {list(PARAMETER_NAMES)}")
        missing = [n for n in PARAMETER_NAMES if n not in values]
        if missing:
            raise ParameterError(f"{source}: missing parameter(s) {missing}")
        out: dict[str, float] = {}
        for name in PARAMETER_NAMES:
            raw = values[name]
            if isinstance(raw, bool) or not isinstance(raw, (int, float)):
                raise ParameterError(f"{source}: parameter {name} must be a number, got {raw!r}")
            out[name] = float(raw)
        return cls(**out)

    @classmethod
    def from_document(cls, doc: object, *, source: str) -> tuple[GeneratorParameters, list[str]]:
        """The eight parameters of a JSON document, and notes on what else it carried.

        Accepted: a ``parameters`` object (a results or truth file), or the eight at the top
        level beside other keys (unit, date, effects...). Keys that are not parameters are
        ignored and named in a note; a missing parameter or a non-number is still an error.
        """
        if not isinstance(doc, Mapping):
            raise ParameterError(f"{source}: expected a JSON object with the eight parameters")
        nested = doc.get("parameters")
        if nested is not None and not isinstance(nested, Mapping):
            raise ParameterError(f"{source}: 'parameters' must be an object of the eight parameters")
        values = nested if nested is not None else doc
        extra = sorted(k for k in values if k not in SPECS_BY_NAME)
        ignored = f"ignored key(s) that are not parameters: {', '.join(map(str, extra))}" if extra else ""
        try:
            params = cls.from_mapping({k: values[k] for k in values if k in SPECS_BY_NAME}, source=source)
        except ParameterError as exc:
            raise ParameterError(f"{exc} ({ignored})" if ignored else str(exc)) from None
        return params, [f"{source}: {ignored}"] if ignored else []

    def replace(self, **changes: float) -> GeneratorParameters:
        return GeneratorParameters(**{**self.as_dict(), **changes})


def validation_problems(values: Mapping[str, float]) -> list[str]:
    """Everything wrong with a parameter set, as short phrases; empty when valid."""
    problems: list[str] = []
    for spec in PARAMETER_SPECS:
        v = values.get(spec.name)
        if v is None:
            continue
        if not math.isfinite(v):
            problems.append(f"{spec.name}={v} is not finite")
        elif (problem := spec.outside(v)) is not None:
            problems.append(problem)
    pairs = (("X_d_prime", "X_d"), ("X_q_prime", "X_q"))
    for small, large in pairs:
        if small in values and large in values and not values[small] < values[large]:
            problems.append(f"{small}={values[small]:g} must be below {large}={values[large]:g}")
    return problems


TABLE1 = GeneratorParameters()
