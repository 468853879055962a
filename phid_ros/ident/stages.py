"""The identification's stages behind one small interface, found by name in a registry.

A stage takes scenarios and what is known before it runs (``known``: parameter name ->
value; X_d and X_q for stage 3, from stage 2, from the user's held values, or from the
tracker's base set) and returns a :class:`StageOutput`: estimates with their uncertainty
and identifiability flags, the stage's problems, and its own result (for the reports and
the JSON). A stage that cannot run raises :class:`~phid_ros.errors.StageError` saying why.

A stage's settings (cut-off frequencies, search bounds, the user's constraints) are its
fields, so the identification pipeline (``ident/pipeline.py``) and the sliding-window
tracker (``stream/tracker.py``) compose the same registered stages, each with its own
settings, and a new method is one class here, registered under its name, with no edit of
the others. Stage 3's methods carry the command line's name for them (``--method fast``,
``--method paper``) as ``method``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

from phid_ros.ident import ieee115, stage1, stage2, stage3
from phid_ros.ident.constraints import NONE, Constraints
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import ScenarioData

if TYPE_CHECKING:
    from phid_ros.ident.identification import IdentifyOptions

TRANSIENT = stage3.TRANSIENT_NAMES


@dataclass
class StageOutput:
    estimates: dict[str, Estimate]
    problems: list[str] = field(default_factory=list)
    result: Any = None  # the stage's own result (Stage1Result, Stage2Result, Stage3Result, BaselineResult)


class Stage(ABC):
    """One step of the identification: scenarios and known parameters in, estimates out."""

    name: ClassVar[str]  # the registry's key: what the stage does
    produces: ClassVar[tuple[str, ...]]
    needs: ClassVar[tuple[str, ...]] = ()  # parameters it takes from ``known``

    @abstractmethod
    def run(self, scenarios: Sequence[ScenarioData], known: Mapping[str, float]) -> StageOutput:
        """The stage's estimates; raises StageError when it cannot run."""


class Stage3Method(Stage):
    """A method of stage 3, chosen by its name on the command line (``phid identify --method``)."""

    method: ClassVar[str]

    @classmethod
    @abstractmethod
    def from_options(cls, opt: IdentifyOptions, earlier: Mapping[str, Estimate]) -> Stage3Method:
        """The method as the identification's options set it (``earlier``: the baseline's estimates)."""


STAGES: dict[str, type[Stage]] = {}
S = TypeVar("S", bound=type[Stage])


def register(cls: S) -> S:
    if cls.name in STAGES:
        raise ValueError(f"stage {cls.name!r} registered twice")
    STAGES[cls.name] = cls
    return cls


def stage3_methods() -> dict[str, type[Stage3Method]]:
    """Stage 3's registered methods by their command-line names (``fast``, ``paper``)."""
    return {cls.method: cls for cls in STAGES.values() if issubclass(cls, Stage3Method)}


@register
@dataclass(frozen=True)
class SwingRegression(Stage):
    """Stage 1: H and D from the swing equation, by regression over every disturbance."""

    name = "swing_regression"
    produces = ("H", "D")
    cutoff_hz: float = stage1.DEFAULT_CUTOFF_HZ
    constraints: Constraints = NONE

    def run(self, scenarios: Sequence[ScenarioData], known: Mapping[str, float]) -> StageOutput:
        r = stage1.swing_regression(scenarios, self.cutoff_hz, self.constraints)
        return StageOutput({"H": r.H, "D": r.D}, [], r)


@register
@dataclass(frozen=True)
class DifferentialDamping(Stage):
    """The paper's stage 1a: D from a torque step with and without damping, H after it."""

    name = "differential_damping"
    produces = ("H", "D")

    def run(self, scenarios: Sequence[ScenarioData], known: Mapping[str, float]) -> StageOutput:
        r = stage1.differential_damping(scenarios)
        return StageOutput({"H": r.H, "D": r.D}, [], r)


@register
@dataclass(frozen=True)
class SteadyStateReactances(Stage):
    """Stage 2: X_d and X_q from the settled states after steps."""

    name = "steady_state_reactances"
    produces = ("X_d", "X_q")

    def run(self, scenarios: Sequence[ScenarioData], known: Mapping[str, float]) -> StageOutput:
        r = stage2.identify_reactances(scenarios)
        return StageOutput({"X_d": r.X_d, "X_q": r.X_q}, list(r.problems), r)


@register
@dataclass(frozen=True)
class Ieee115CurveFits(Stage):
    """The IEEE 115 baseline: envelope curve fits of the fault currents, bounded around X_d, X_q (18), (21)."""

    name = "ieee115_curve_fits"
    produces = TRANSIENT
    needs = ("X_d", "X_q")
    seed: int = 0

    def run(self, scenarios: Sequence[ScenarioData], known: Mapping[str, float]) -> StageOutput:
        if "X_d" not in known or "X_q" not in known:
            raise ieee115.BaselineError("the IEEE 115 baseline needs X_d and X_q for its bounds (18), (21)")
        r = ieee115.identify(scenarios, known["X_d"], known["X_q"], seed=self.seed)
        return StageOutput(r.estimates(), list(r.problems), r)


@dataclass(frozen=True)
class _StateConsistency(Stage3Method):
    """Stage 3's data: the scenarios prefiltered and cut to ``window_s`` after each event (None: whole)."""

    produces = TRANSIENT
    needs = ("X_d", "X_q")
    prefilter_hz: float | None = stage3.DEFAULT_PREFILTER_HZ
    window_s: float | None = 12.0
    constraints: Constraints = NONE

    def data(self, scenarios: Sequence[ScenarioData]) -> stage3.Stage3Data:
        return stage3.prepare(scenarios, self.prefilter_hz, window_s=self.window_s)

    @staticmethod
    def output(r: stage3.Stage3Result, extra: dict[str, Estimate] | None = None) -> StageOutput:
        return StageOutput({n: getattr(r, n) for n in TRANSIENT} | (extra or {}), list(r.problems), r)


@register
@dataclass(frozen=True)
class VariableProjection(_StateConsistency):
    """Stage 3 by variable projection: two 1-D searches over the time constants, the rest linear.

    Without X_d and X_q known (stage 2 could not run) it refines them itself from 2.0 pu and
    returns them too. ``bounds_d``, ``bounds_q`` narrow the time-constant searches (a tracker's
    warm start around its last hop).
    """

    name = "variable_projection"
    method = "fast"
    refine_synchronous: bool = False
    bounds_d: tuple[float, float] | None = None
    bounds_q: tuple[float, float] | None = None

    @classmethod
    def from_options(cls, opt: IdentifyOptions, earlier: Mapping[str, Estimate]) -> Stage3Method:
        return cls(
            prefilter_hz=opt.prefilter_hz, constraints=opt.constraints, refine_synchronous=opt.refine_synchronous
        )

    def run(self, scenarios: Sequence[ScenarioData], known: Mapping[str, float]) -> StageOutput:
        x_d, x_q = known.get("X_d"), known.get("X_q")
        missing = x_d is None or x_q is None
        r = stage3.variable_projection(
            self.data(scenarios),
            x_d or 2.0,
            x_q or 2.0,
            refine_synchronous=self.refine_synchronous or missing,
            bounds_d=self.bounds_d,
            bounds_q=self.bounds_q,
            constraints=self.constraints,
        )
        return self.output(r, dict(r.refined) if missing else {})


@register
@dataclass(frozen=True)
class GlobalSearch(_StateConsistency):
    """Stage 3 as the paper runs it: differential evolution (or another global optimiser) on J,
    then multi-start L-BFGS-B; ``prior``: the IEEE 115 estimates with weight lambda (the paper's option)."""

    name = "global_search"
    method = "paper"
    prior: tuple[float, ...] | None = None
    seed: int = 0
    maxiter: int = 300

    @classmethod
    def from_options(cls, opt: IdentifyOptions, earlier: Mapping[str, Estimate]) -> Stage3Method:
        prior = None
        if opt.use_prior and all(n in earlier for n in TRANSIENT):
            prior = tuple(earlier[n].value for n in TRANSIENT)
        return cls(
            prefilter_hz=opt.prefilter_hz,
            constraints=opt.constraints,
            prior=prior,
            seed=opt.seed,
            maxiter=opt.paper_maxiter,
        )

    def run(self, scenarios: Sequence[ScenarioData], known: Mapping[str, float]) -> StageOutput:
        if "X_d" not in known or "X_q" not in known:
            raise stage3.Stage3Error("the paper method needs X_d and X_q from stage 2")
        r = stage3.global_search(
            self.data(scenarios),
            known["X_d"],
            known["X_q"],
            prior=self.prior,
            seed=self.seed,
            maxiter=self.maxiter,
            constraints=self.constraints,
        )
        return self.output(r)
