"""Excitation systems and turbine-governors as PSS/E defines them: their data apart from their equations.

Each model declares its parameters once (PSS/E's name, unit, range, meaning) and its
small-signal path: the response of its output deviation to its input deviations from rest, the
blocks of PSS/E's diagram with the limits left out. A limit is a parameter the recordings
determine only where the output reached it; identification reports it as not determined
otherwise (:mod:`phid_ros.controls.identify`). A new model is one class here, registered; the
identification and the JSON take every registered model of a kind as a candidate.

Blocks (Tustin-free: each first-order lag is :func:`phid_ros.numerics.first_order_response`,
exact for inputs linear between samples):
``lag(T)`` = 1/(1 + sT); ``lead_lag(T_lead, T_lag)`` = (1 + sT_lead)/(1 + sT_lag)
= T_lead/T_lag + (1 - T_lead/T_lag) lag(T_lag).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from phid_ros.numerics import first_order_response

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ControlParameter:
    """One constant of a control model's PSS/E record."""

    name: str  # PSS/E's
    unit: str
    default: float
    low: float
    high: float
    meaning: str
    limit: bool = False  # an output or state limit: determined only where the data reached it
    absent: float | None = None  # the value at which its term vanishes (a turbine damping of 0)

    def outside(self, value: float) -> bool:
        return not self.low <= value <= self.high


@dataclass(frozen=True)
class ControlInputs:
    """One scenario's deviations from its pre-event steady state, on its sample grid."""

    dt: float
    v_t: Array  # terminal voltage deviation, pu
    speed: Array  # rotor speed deviation, pu
    reference_step: Array  # the unit step at the scenario's reference change (zeros if none)


def lag(u: Array, tau: float, dt: float) -> Array:
    """1/(1 + s tau) from rest; a vanishing tau is a wire."""
    return u if tau <= 1e-6 else first_order_response(u, tau, dt)


def lead_lag(u: Array, t_lead: float, t_lag: float, dt: float) -> Array:
    """(1 + s t_lead)/(1 + s t_lag) from rest."""
    if t_lag <= 1e-6:
        return u
    r = t_lead / t_lag
    return r * u + (1.0 - r) * first_order_response(u, t_lag, dt)


class ControlModel(ABC):
    """A control system's small-signal path; subclass and :func:`register` to add one."""

    name: ClassVar[str]
    kind: ClassVar[str]  # "exciter" (output E_fd) or "governor" (output P_m)
    description: ClassVar[str]
    parameters: ClassVar[tuple[ControlParameter, ...]]

    @classmethod
    def fitted(cls) -> tuple[ControlParameter, ...]:
        return tuple(p for p in cls.parameters if not p.limit)

    @classmethod
    def defaults(cls) -> dict[str, float]:
        return {p.name: p.default for p in cls.parameters}

    @classmethod
    @abstractmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        """The output's deviation for the scenario's inputs; ``reference`` is the size of the
        reference step (V_ref for an exciter, P_ref in pu power for a governor)."""


MODELS: dict[str, type[ControlModel]] = {}


def register(cls: type[ControlModel]) -> type[ControlModel]:
    MODELS[cls.name] = cls
    return cls


def of_kind(kind: str) -> list[type[ControlModel]]:
    return [m for m in MODELS.values() if m.kind == kind]


@register
class SEXS(ControlModel):
    """Simplified excitation system: (V_ref - V_t) through (1 + sT_A)/(1 + sT_B), K/(1 + sT_E)."""

    name = "SEXS"
    kind = "exciter"
    description = "simplified excitation system (PSS/E SEXS)"
    parameters = (
        ControlParameter("TA/TB", "", 0.1, 0.01, 1.0, "lead-lag ratio T_A/T_B"),
        ControlParameter("TB", "s", 10.0, 0.1, 30.0, "lag time constant T_B"),
        ControlParameter("K", "pu", 100.0, 5.0, 1000.0, "steady-state gain"),
        ControlParameter("TE", "s", 0.05, 0.002, 2.0, "exciter time constant T_E"),
        ControlParameter("EMIN", "pu", -5.0, -20.0, 0.0, "minimum field voltage", limit=True),
        ControlParameter("EMAX", "pu", 5.0, 1.0, 20.0, "maximum field voltage", limit=True),
    )

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        tb = values["TB"]
        e = reference * x.reference_step - x.v_t
        return values["K"] * lag(lead_lag(e, values["TA/TB"] * tb, tb, x.dt), values["TE"], x.dt)


@register
class TGOV1(ControlModel):
    """Steam turbine-governor: (P_ref - dw/R) through 1/(1 + sT_1), (1 + sT_2)/(1 + sT_3), less D_t dw."""

    name = "TGOV1"
    kind = "governor"
    description = "steam turbine-governor (PSS/E TGOV1)"
    parameters = (
        ControlParameter("R", "pu", 0.05, 0.01, 0.5, "permanent droop"),
        ControlParameter("T1", "s", 0.5, 0.02, 5.0, "governor (valve) time constant"),
        ControlParameter("VMAX", "pu", 1.0, 0.5, 1.5, "maximum valve position", limit=True),
        ControlParameter("VMIN", "pu", 0.0, -0.5, 0.5, "minimum valve position", limit=True),
        ControlParameter("T2", "s", 1.0, 0.0, 20.0, "turbine lead time constant"),
        ControlParameter("T3", "s", 3.0, 0.05, 30.0, "turbine lag (reheat) time constant"),
        ControlParameter("Dt", "pu", 0.0, 0.0, 5.0, "turbine damping", absent=0.0),
    )

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        valve = lag(reference * x.reference_step - x.speed / values["R"], values["T1"], x.dt)
        return lead_lag(valve, values["T2"], values["T3"], x.dt) - values["Dt"] * x.speed
