"""A control model's data apart from its equations: its parameters (PSS/E's name, unit, range,
meaning), its limits, and the registry every model of a kind is a candidate from."""

from __future__ import annotations

import copy
import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Self, TypeVar

import numpy as np

from phid_ros.controls.models.blocks import (
    Array,
    ControlInputs,
)
from phid_ros.model.bounds import Bounded


@dataclass(frozen=True)
class ControlParameter(Bounded):
    """One constant of a control model's PSS/E record; ``low``..``high`` is the fit's search range
    (the shared range check, :class:`~phid_ros.model.bounds.Bounded`)."""

    name: str  # PSS/E's
    unit: str
    default: float
    low: float
    high: float
    meaning: str
    limit: bool = False  # an output or state limit: determined only where the data reached it
    absent: float | None = None  # the value at which its term vanishes (a turbine damping of 0)
    within: str | None = None  # the constant whose term this one belongs to: moot where that one is absent
    held: bool = False  # not fitted: the model's structure holds it at its default (a stage left out)

    def record_problem(self, value: float) -> str | None:
        """What makes a record's value one the simulation cannot take, or None. Not the fit's
        search range: a published record carries what its fit found (ESST5B T_B2 = 5.1 ms), and
        the play-in integrates any positive time constant exactly (first-order hold)."""
        if not math.isfinite(value):
            return "is not a number"
        if self.unit == "s" and value < 0:
            return "is a negative time constant"
        return None


class LimitsError(ValueError):
    """A record's limits that cannot hold the recorded operating point: not simulated."""


@dataclass(frozen=True)
class OperatingLevels:
    """Where an exciter and the machine stood before the event: what its limits are measured
    against (a static exciter's ceiling is proportional to V_T and lowered by K_C I_FD)."""

    v_t: Array  # the terminal voltage (pu) on the inputs' grid
    output0: float  # E_fd before the event, machine pu
    i_fd0: float  # the field current before the event, machine pu (E_fd at rest)


class ControlModel(ABC):
    """A control system's small-signal path; subclass and :func:`register` to add one.

    A model is a value: :data:`MODELS` holds one instance of each registered class, and a model
    with some constants held (a term the recordings do not show, held where it vanishes) is
    another instance of the same class, :meth:`with_parameters`, as a plant effect's trial is
    another instance of its effect. The constants' values travel beside it as a mapping by
    PSS/E's names, the form a record and a fit carry them in."""

    name: str
    kind: str  # "exciter" (output E_fd), "governor" (output P_m) or "stabiliser" (output V_S)
    description: str
    parameters: tuple[ControlParameter, ...]
    # integers a .dyr record carries before the constants (PSS/E's ICONs), with the values phid writes
    icons: tuple[tuple[str, int], ...] = ()
    # the ICONs whose value the simulation depends on (an input's code, a filter's order): a
    # record that gives another is refused, not simulated as phid's
    icons_simulated: tuple[str, ...] = ()
    # channels a model reads beyond its kind's (a dual-input stabiliser's rotor speed)
    needs: tuple[str, ...] = ()
    # constants of branches the small-signal path does not pass through (said in a validation)
    outside_path: tuple[str, ...] = ()
    # limits :meth:`limited` simulates (said apart from the ones the play-in leaves out)
    simulated_limits: tuple[str, ...] = ()
    # (lower, upper): the limits that bound the output itself, which a recorded flat top pins
    output_limits: tuple[str, str] | None = None
    # (lower, upper): the limits on the regulator's input (its error), which no flat top shows:
    # found where the fit wants them (:func:`phid_ros.controls.limits.wanted_input_limits`)
    input_limits: tuple[str, str] | None = None
    # the constant that lowers the output's ceiling with the field current (a static exciter's
    # rectifier loading K_C): fitted beside a ceiling the recordings reached
    loading: str | None = None
    simulated_limits_how: str = ""
    # the planning tools' own forms of the model, where phid writes them: PSLF's record is PSS/E's
    # constants after ``mwcap=`` and this many zeros (None: its layout not known, not written);
    # ANDES's model of the same name (its constants under ``andes_names`` where they differ)
    pslf_trailing_zeros: int | None = None
    in_andes: bool = False
    andes_names: Mapping[str, str] = {}

    def with_parameters(self, parameters: Iterable[ControlParameter]) -> Self:
        """This model with its parameters declared otherwise (held, or another search range)."""
        other = copy.copy(self)
        other.parameters = tuple(parameters)
        return other

    def __repr__(self) -> str:
        declared = {p.name for p in type(self).parameters if p.held}
        held = [p.name for p in self.parameters if p.held and p.name not in declared]
        return f"{type(self).__name__}()" if not held else f"{type(self).__name__}(held={held})"

    def fitted(self) -> tuple[ControlParameter, ...]:
        return tuple(p for p in self.parameters if not p.limit and not p.held and p.high > p.low)

    def start(self, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        """Where the fit starts, given the fits of the models registered before it (by name): a
        model that nests a simpler one starts where that one ended, so it fits at least as well
        (a rate feedback's loop has local minima a start from the defaults falls into)."""
        return self.defaults()

    def started_from(
        self,
        earlier: Mapping[str, Mapping[str, float]],
        simpler: str,
        nested: Callable[[Mapping[str, float]], Mapping[str, float]],
    ) -> dict[str, float]:
        """:meth:`start` for a model that nests ``simpler``: its defaults, with ``nested`` of the
        simpler model's fit (the constants that play it) where that one was fitted."""
        fit = earlier.get(simpler)
        return {**self.defaults(), **nested(fit)} if fit else self.defaults()

    def completed(self, values: Mapping[str, float]) -> dict[str, float]:
        """The constants that follow from the fitted ones (none unless a model says so)."""
        return dict(values)

    def record_problem(self, values: Mapping[str, float]) -> str | None:
        """What makes a record's constants ones the simulation cannot take, or None: a constant
        not a number or a negative time constant (held ones too: the play-in runs a record as
        written, T_5 = -3 s included), and a limit pair whose lower bound lies above its upper (an
        IEEEST with LSMAX below LSMIN played to an E_fd error of 9e266 pu)."""
        for q in self.parameters:
            problem = q.record_problem(values[q.name])
            if problem is not None:
                return f"{q.name} = {values[q.name]:g} {problem}"
        for pair in (self.output_limits, self.input_limits):
            if pair is not None and values[pair[0]] > values[pair[1]]:
                lo, hi = pair
                return f"{lo} = {values[lo]:g} lies above {hi} = {values[hi]:g}: the lower limit is above the upper"
        return None

    def recorded(self, values: Mapping[str, float]) -> dict[str, float]:
        """A record's constants as the simulation takes them: as written (a model whose record
        can carry what phid does not simulate refuses it here, naming the constants)."""
        return dict(values)

    def not_simulated(self, values: Mapping[str, float]) -> list[str]:
        """What a record of this model carries that the small-signal play-in leaves out, with the
        record's values: its limits (and the exciter saturation, the rectifier loading, which act
        only at large signals) and the branches outside its path."""
        out = []
        limits = [p for p in self.parameters if p.limit and p.name not in self.simulated_limits]
        if self.simulated_limits and self.simulated_limits_how:
            out.append(f"{self.name}: {self.simulated_limits_how}")
        if limits:
            named = ", ".join(f"{p.name} = {values[p.name]:g}" for p in limits)
            out.append(
                f"{self.name} {named} (the play-in is small-signal: a recording that reaches them is not followed)"
            )
        idle = [p for p in self.parameters if p.name in self.outside_path]
        if idle:
            named = ", ".join(f"{p.name} = {values[p.name]:g}" for p in idle)
            out.append(f"{self.name} {named} ({idle[0].meaning})")
        return out

    def limited(
        self, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        """The output's deviation with the limits the model declares simulated, from the
        operating levels; None where the model has only its small-signal path."""
        return None

    def output_clipped(
        self, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array:
        """The small-signal response held within the output limits (a stabiliser's V_S band)."""
        assert self.output_limits is not None
        lower, upper = self.output_limits
        out = self.response(values, x, reference) + levels.output0
        return np.clip(out, values[lower], values[upper]) - levels.output0

    def input_signal(
        self, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        """The signal at the input limiter (absolute, pu) with that limiter open; None where the
        model declares no input limit."""
        return None

    def limit_at(self, name: str, output: float, levels: OperatingLevels, k: int) -> float:
        """The value of limit ``name`` that puts the output's bound at ``output`` at sample ``k``
        (a recorded flat top where the output sat on it): the output itself for a limit on the
        output, divided by V_T for a static exciter's ceiling (see ESST5B)."""
        return output

    def defaults(self) -> dict[str, float]:
        return {p.name: p.default for p in self.parameters}

    @abstractmethod
    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        """The output's deviation for the scenario's inputs; ``reference`` is the size of the
        reference step (V_ref for an exciter, P_ref in pu power for a governor)."""


# a model's data as declared above (what a model seen through another, or a copy, carries over)
MODEL_DATA = (
    "name",
    "kind",
    "description",
    "parameters",
    "icons",
    "icons_simulated",
    "needs",
    "outside_path",
    "simulated_limits",
    "output_limits",
    "input_limits",
    "loading",
    "simulated_limits_how",
    "pslf_trailing_zeros",
    "in_andes",
    "andes_names",
)

MODELS: dict[str, ControlModel] = {}  # one instance of each registered model, by PSS/E's name


KINDS_IN_ORDER = ("exciter", "governor", "stabiliser")  # every kind a model is of, as the unit's records go


_Model = TypeVar("_Model", bound=type[ControlModel])


def register(cls: _Model) -> _Model:
    """Class decorator: the model's instance joins :data:`MODELS` (registration order is the
    choice's order among equals)."""
    MODELS[cls.name] = cls()
    return cls


def of_kind(kind: str) -> list[ControlModel]:
    return [m for m in MODELS.values() if m.kind == kind]


# the terminal-voltage transducer's lag, where an exciter model has one (absent at 0)
TRANSDUCER = ControlParameter("TR", "s", 0.0, 0.0, 0.5, "voltage transducer time constant", absent=0.0)
