"""The stages behind one interface: the registry, a method added from outside, and what each needs."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import pytest

from phid_ros.errors import StageError
from phid_ros.ident import stages
from phid_ros.ident.pipeline import IdentifyOptions, identify
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.stages import (
    STAGES,
    GlobalSearch,
    Ieee115CurveFits,
    Stage3Method,
    StageOutput,
    SteadyStateReactances,
    SwingRegression,
    VariableProjection,
    register,
    stage3_methods,
)
from phid_ros.model.parameters import TABLE1


def test_every_stage_is_registered_under_what_it_does() -> None:
    assert set(STAGES) == {
        "swing_regression",
        "differential_damping",
        "steady_state_reactances",
        "ieee115_curve_fits",
        "variable_projection",
        "global_search",
    }
    assert {m: c.name for m, c in stage3_methods().items()} == {"fast": "variable_projection", "paper": "global_search"}
    with pytest.raises(ValueError, match="registered twice"):
        register(type("Again", (SwingRegression,), {}))


def test_a_method_registered_from_outside_runs_in_the_identification(clean_scenarios, monkeypatch) -> None:
    """A new stage-3 method is one class: the pipeline finds it by its command-line name."""
    seen: dict[str, float] = {}

    @dataclass(frozen=True)
    class Datasheet(Stage3Method):
        name = "datasheet_transients"
        method = "datasheet"
        produces = stages.TRANSIENT
        needs = ("X_d", "X_q")

        @classmethod
        def from_options(cls, opt: IdentifyOptions, earlier: Mapping[str, Estimate]) -> Stage3Method:
            return cls()

        def run(self, scenarios: Sequence[ScenarioData], known: Mapping[str, float]) -> StageOutput:
            seen.update(known)
            return StageOutput({n: Estimate(getattr(TABLE1, n), 0.0) for n in self.produces}, ["from the datasheet"])

    monkeypatch.setitem(STAGES, Datasheet.name, Datasheet)
    res = identify(clean_scenarios, IdentifyOptions(method="datasheet", baseline=False, validate=False))
    # X_d and X_q reach it from the registered stage 2, which ran before it
    assert seen == pytest.approx({"X_d": TABLE1.X_d, "X_q": TABLE1.X_q}, rel=2e-3)
    for n in stages.TRANSIENT:
        assert res.estimates[n].value == getattr(TABLE1, n)
    assert res.estimates["H"].value == pytest.approx(TABLE1.H, rel=2e-3)
    assert "stage 3: from the datasheet" in res.problems
    with pytest.raises(ValueError, match="method must be one of"):
        identify(clean_scenarios, IdentifyOptions(method="nonesuch"))


def test_the_stages_run_alone_on_scenarios_and_known_values(noisy_scenarios) -> None:
    h_d = SwingRegression().run(noisy_scenarios, {})
    assert set(h_d.estimates) == {"H", "D"}
    assert h_d.estimates["H"].value == pytest.approx(TABLE1.H, rel=0.01)
    x = SteadyStateReactances().run(noisy_scenarios, {})
    known = {n: e.value for n, e in x.estimates.items()}
    assert known == pytest.approx({"X_d": TABLE1.X_d, "X_q": TABLE1.X_q}, rel=0.01)
    r3 = VariableProjection().run(noisy_scenarios, known)
    assert set(r3.estimates) == set(stages.TRANSIENT)
    for n in stages.TRANSIENT:
        assert r3.estimates[n].value == pytest.approx(getattr(TABLE1, n), rel=0.01), n
        assert r3.estimates[n].std > 0


def test_state_consistency_without_known_reactances_refines_them_or_says_it_cannot(noisy_scenarios) -> None:
    out = VariableProjection().run(noisy_scenarios, {})
    assert out.estimates["X_d"].value == pytest.approx(TABLE1.X_d, rel=0.01)
    assert out.estimates["X_q"].value == pytest.approx(TABLE1.X_q, rel=0.01)
    assert "stage 2 could not run" in out.estimates["X_d"].note
    # estimated jointly with X' and T', so with an error bar of its own (it was published with none)
    for n in ("X_d", "X_q"):
        est = out.estimates[n]
        assert 0 < est.std < 0.05 * est.value and est.identifiable, n
        assert abs(est.value - getattr(TABLE1, n)) < 3 * est.std, n
    with pytest.raises(StageError, match="needs X_d and X_q"):
        GlobalSearch().run(noisy_scenarios, {"X_d": TABLE1.X_d})
    with pytest.raises(StageError, match="needs X_d and X_q"):
        Ieee115CurveFits().run(noisy_scenarios, {})
