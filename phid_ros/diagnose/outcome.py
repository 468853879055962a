"""What a diagnosis finds: the scores of a model on held-out data, each round's trials, the diagnosis."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from phid_ros.diagnose.fit import FitResult
from phid_ros.ident.scenario import ScenarioData
from phid_ros.model.parameters import PARAMETER_NAMES, GeneratorParameters


@dataclass
class ChannelError:
    rmse: float  # against the measurement, in the channel's unit (includes sensor noise)
    unexplained: float  # the residual with its white-noise share removed, in the channel's unit


@dataclass
class Score:
    """How well one model explains the held-out scenarios."""

    channels: dict[str, ChannelError]
    overall: float  # RMS over channels of the unexplained error in units of sensor noise

    def as_dict(self) -> dict[str, Any]:
        return {"overall": self.overall, "channels": {c: e.__dict__ for c, e in self.channels.items()}}


@dataclass
class Trial:
    candidate: str
    settings: dict[str, Any]
    fit: FitResult | None
    screened_chi2: float
    heldout: Score | None = None
    delta_bic: float = math.nan
    heldout_gain: float = math.nan
    presence: float | None = None  # standard deviations from the effect's absence (None: cannot say)
    accepted: bool = False


@dataclass
class Round:
    trials: list[Trial]
    chosen: str | None


@dataclass
class Diagnosis:
    identified: dict[str, float]  # the fourth-order model as the three-stage identification gave it
    base_fit: FitResult  # the same structure refitted by output error: the "before" model
    final: FitResult
    rounds: list[Round]
    before: Score
    after: Score
    steps: list[tuple[str, Score]]  # the held-out score after adding each named effect
    fit_windows: list[ScenarioData]
    heldout_windows: list[ScenarioData]
    sigma: dict[str, float]
    seconds: float = 0.0
    problems: list[str] = field(default_factory=list)
    # the final base parameters the data determine (determined(): a two-point profile each)
    identifiable: dict[str, bool] = field(default_factory=dict)
    uncertainty: dict[str, float] = field(default_factory=dict)
    held: list[str] = field(default_factory=list)  # base parameters kept at their identified values
    # per named effect, whether the data determine each of its numeric parameters (determined())
    effects_identifiable: dict[str, dict[str, bool]] = field(default_factory=dict)
    # the base parameters the three-stage identification left at a search bound: its value there
    # is a bound, not an identified value (the diagnosis searches them over their whole range)
    identified_at_bound: tuple[str, ...] = ()

    @property
    def named(self) -> list[str]:
        return self.final.model.names


def parameter_errors(values: Mapping[str, float], truth: GeneratorParameters) -> dict[str, float]:
    t = truth.as_dict()
    return {n: 100.0 * (values[n] / t[n] - 1.0) for n in PARAMETER_NAMES if t[n]}
