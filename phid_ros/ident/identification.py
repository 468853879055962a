"""What an identification is asked (:class:`IdentifyOptions`) and what it gives
(:class:`IdentificationResult`): the types the pipeline, the routes of a recorder's channels
(``ident/determinable.py``) and the stages (``ident/stages.py``) share, in a module none of them
is, so that each imports them without importing the others.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from phid_ros.ident import stage1, stage2, stage3
from phid_ros.ident.constraints import NONE, Constraints
from phid_ros.ident.results import Estimate
from phid_ros.ident.route_figures import RouteFigures
from phid_ros.ident.scenario import DEFAULT_THRESHOLDS, ScenarioData, StepThresholds
from phid_ros.ident.validation import ValidationResult
from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ
from phid_ros.model.parameters import PARAMETER_NAMES, GeneratorParameters, validation_problems

Say = Callable[[str], None]  # hears each step of an identification


@dataclass
class IdentifyOptions:
    method: str = "fast"
    stage1_cutoff_hz: float = stage1.DEFAULT_CUTOFF_HZ
    prefilter_hz: float | None = stage3.DEFAULT_PREFILTER_HZ
    refine_synchronous: bool = False
    use_prior: bool = False  # paper: IEEE 115 estimates as prior with lambda 0.2
    baseline: bool = True
    validate: bool = True
    f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ
    seed: int = 0
    paper_maxiter: int = 300
    # the smallest unlabelled steps taken as disturbances when windows are cut (labelled ones count at any size)
    step_thresholds: StepThresholds = DEFAULT_THRESHOLDS
    constraints: Constraints = NONE  # --fix, --bounds, --start: held values, bounds, starting values


@dataclass
class IdentificationResult:
    estimates: dict[str, Estimate]
    method: str
    scenarios: list[ScenarioData]
    baseline: dict[str, Estimate] = field(default_factory=dict)
    stage1_paper: stage1.Stage1Result | None = None
    stage1: stage1.Stage1Result | None = None
    stage2: stage2.Stage2Result | None = None
    stage3: stage3.Stage3Result | None = None
    validation: ValidationResult | None = None
    validation_truth: ValidationResult | None = None
    problems: list[str] = field(default_factory=list)
    timing: dict[str, float] = field(default_factory=dict)
    constraints: Constraints = NONE
    # with channels missing: parameter -> the route that determined it (ident/determinable.py)
    determined_by: dict[str, str] = field(default_factory=dict)
    route_details: dict[str, RouteFigures] = field(default_factory=dict)  # those routes' own figures (JSON "stages")
    # of ``problems``, the scenarios whose label the signals dispute (kept): a diagnosis and a fleet's
    # row say them where the scenarios are cut, not again as the identification's
    label_disputes: list[str] = field(default_factory=list)

    def light(self) -> IdentificationResult:
        """The estimates and what was said of them, without the scenarios' samples and the stages'
        arrays (a long replay keeps one of these per recalibration)."""
        return IdentificationResult(
            self.estimates,
            self.method,
            [],
            problems=list(self.problems),
            constraints=self.constraints,
            label_disputes=list(self.label_disputes),
            determined_by=dict(self.determined_by),
        )

    @property
    def parameters(self) -> dict[str, float]:
        return {n: self.estimates[n].value if n in self.estimates else math.nan for n in PARAMETER_NAMES}

    def published(self) -> tuple[str, ...]:
        """The parameters identified: those the JSON, the topic and the record give as numbers."""
        e = self.estimates
        return tuple(n for n in PARAMETER_NAMES if n in e and e[n].identifiable and math.isfinite(e[n].value))

    def at_bound(self) -> tuple[str, ...]:
        """Parameters left at a search bound of their stage: their values carry no information."""
        return tuple(n for n in PARAMETER_NAMES if n in self.estimates and self.estimates[n].at_bound)

    def stage1_held(self) -> tuple[str, ...]:
        """What a diagnosis holds at this result: D, when stage 1 identified it (see
        ``DiagnoseOptions.held``)."""
        d = self.estimates.get("D")
        return ("D",) if d is not None and d.identifiable and math.isfinite(d.value) else ()

    def complete(self) -> GeneratorParameters | None:
        """The identified set as a model, if all eight exist and are physically valid."""
        p = self.parameters
        if any(not math.isfinite(v) for v in p.values()) or validation_problems(p):
            return None
        return GeneratorParameters(**p)

    def to_json(self, truth: GeneratorParameters | None = None) -> dict[str, Any]:
        p = self.parameters
        published = self.published()
        doc: dict[str, Any] = {
            # a withheld value is null here (the contract), and kept apart with its reason: a
            # reader that takes ``parameters`` never takes a number the data did not give
            "parameters": {n: p[n] if n in published else None for n in PARAMETER_NAMES},
            "uncertainty": {n: self.estimates[n].std if n in published else None for n in PARAMETER_NAMES},
            "identifiable": {n: n in published for n in PARAMETER_NAMES},
            "withheld": {
                n: {"value": e.value, "std": e.std, "bound": e.bound or None, "why": e.note}
                for n, e in self.estimates.items()
                if n not in published and math.isfinite(e.value)
            },
            "drivers": {n: self.estimates[n].drivers if n in self.estimates else [] for n in PARAMETER_NAMES},
            "method": self.method,
            "events": [
                {
                    "name": s.name,
                    "kind": s.kind,
                    "role": s.role,
                    "generator_damping": s.generator_damping,
                    "event_time_s": s.k_event * s.dt,
                    "clearing_time_s": None if s.k_clear is None else s.k_clear * s.dt,
                    "start_ns": s.start_ns,
                    "notes": s.notes,
                }
                for s in self.scenarios
            ],
            "validation": self.validation.as_dict() if self.validation else None,
            "baseline_ieee115": {n: e.value for n, e in self.baseline.items()},
            "stages": self._stage_details(),
            "problems": self.problems,
            "timing_s": self.timing,
        }
        if self.constraints:
            doc["constraints"] = self.constraints.as_dict()
        point = operating_point(self.scenarios)
        if point:
            doc["operating_point"] = point
        if self.determined_by:
            doc["determined_by"] = self.determined_by
        if self.stage1_paper is not None:
            doc["stage1_differential_damping"] = {
                "H": self.stage1_paper.H.value,
                "D": self.stage1_paper.D.value,
                "pairs": self.stage1_paper.details.get("pairs", []),
            }
        if truth is not None:
            t = truth.as_dict()
            doc["truth"] = t
            doc["errors_pct"] = {
                n: 100.0 * (p[n] / t[n] - 1.0) if n in published and t[n] else None for n in PARAMETER_NAMES
            }
            for n, w in doc["withheld"].items():  # how far the value withheld was (a simulated set's study)
                w["error_pct"] = 100.0 * (w["value"] / t[n] - 1.0) if t[n] else None
            doc["baseline_errors_pct"] = {
                n: 100.0 * (e.value / t[n] - 1.0) for n, e in self.baseline.items() if math.isfinite(e.value) and t[n]
            }
            if self.validation_truth is not None:
                doc["validation_vs_measurement"] = self.validation_truth.as_dict()
        return doc

    def _stage_details(self) -> dict[str, Any]:
        out: dict[str, Any] = {key: figures.as_dict() for key, figures in self.route_details.items()}
        if self.stage1:
            out["stage1"] = {"method": self.stage1.method, **self.stage1.details}
        if self.stage2:
            out["stage2"] = {
                "method_d": self.stage2.method_d,
                "method_q": self.stage2.method_q,
                "r2_d": self.stage2.r2_d,
                "r2_q": self.stage2.r2_q,
                "steady_points": [pt.__dict__ for pt in self.stage2.points],
            }
        if self.stage3:
            out["stage3"] = {
                "method": self.stage3.method,
                "objective": self.stage3.objective,
                "evaluations": self.stage3.evaluations,
                "seconds": self.stage3.seconds,
                "X_d_used": self.stage3.X_d,
                "X_q_used": self.stage3.X_q,
            }
        return out


OPERATING_CHANNELS = {"p_m": "p_m_pu", "p_e": "p_e_pu", "q_e": "q_e_pu", "v_t": "v_t_pu"}


def operating_point(scenarios: Sequence[ScenarioData]) -> dict[str, float]:
    """The mean pre-event P_m, P_e, Q_e, V_t of the identification scenarios (machine base): where
    the identified model was linearised. A planning model whose swing equation divides P_m by the
    speed (PSS/E's) needs it to carry D over (:mod:`phid_ros.export.record`); without a P_m channel
    P_m is P_e before the event (R_a = 0)."""
    ident = [s for s in scenarios if s.role == "identify"]
    out: dict[str, float] = {}
    for c, key in OPERATING_CHANNELS.items():
        have = [s for s in ident if s.has(c)] or ([s for s in ident if s.has("p_e")] if c == "p_m" else [])
        values = [float(np.nanmean(s[c if s.has(c) else "p_e"][s.pre_slice()])) for s in have]
        if values and all(math.isfinite(v) for v in values):
            out[key] = float(np.mean(values))
    return out
