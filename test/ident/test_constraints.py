"""--fix, --bounds, --start: every stage holds what the user holds, and the error bars are recomputed."""

from __future__ import annotations

import re

import pytest

from phid_ros.errors import ParameterError
from phid_ros.ident.constraints import parse_constraints
from phid_ros.ident.pipeline import IdentifyOptions, identify
from phid_ros.model.parameters import TABLE1

TRUTH = TABLE1.as_dict()


@pytest.fixture(scope="module")
def scenarios(noisy_scenarios):
    return noisy_scenarios  # the paper catalogue, 12 s windows (conftest)


@pytest.fixture(scope="module")
def free(scenarios):
    return identify(scenarios, IdentifyOptions(baseline=False, validate=False)).estimates


def run(scenarios, method: str = "fast", **kw):
    constraints = parse_constraints(**kw)
    opts = IdentifyOptions(method=method, baseline=False, validate=False, paper_maxiter=25, constraints=constraints)
    return identify(scenarios, opts)


def test_a_held_value_is_used_and_the_others_error_bars_recomputed(scenarios, free) -> None:
    res = run(scenarios, fix=["D=0.4", "X_q_prime=0.814"])
    e = res.estimates
    assert (e["D"].value, e["D"].std, e["D"].identifiable) == (0.4, 0.0, True) and "held at 0.4" in e["D"].note
    assert e["X_q_prime"].value == 0.814
    # H from the swing regression without its D column; T'_q0 without X'_q's
    assert e["H"].std != free["H"].std and abs(e["H"].value / TRUTH["H"] - 1) < 1e-3
    assert e["T_q0_prime"].std < free["T_q0_prime"].std
    err = {
        k: abs(v.value / TRUTH["T_q0_prime"] - 1) for k, v in (("held", e["T_q0_prime"]), ("free", free["T_q0_prime"]))
    }
    assert err["held"] < err["free"], err
    assert res.to_json()["constraints"]["fixed"] == {"D": 0.4, "X_q_prime": 0.814}


def test_held_synchronous_reactances_skip_stage2(scenarios) -> None:
    e = run(scenarios, fix=["X_d=2.6", "X_q=2.41"]).estimates
    assert (e["X_d"].value, e["X_q"].value) == (2.6, 2.41)
    assert e["X_d_prime"].value != pytest.approx(0.5, rel=1e-4)  # stage 3 worked with the held 2.6


def test_an_estimate_pushed_onto_a_bound_is_flagged(scenarios, free) -> None:
    e = run(scenarios, bounds=["H=3.0:3.3", "T_q0_prime=0.10:0.13"]).estimates
    assert e["H"].value == 3.3 and e["H"].at_bound and not e["H"].identifiable
    assert re.search(r"pull it to 3\.4\d+, beyond the bound 3\.3", e["H"].note), e["H"].note
    assert e["D"].value != free["D"].value  # re-estimated with H at its bound
    assert e["T_q0_prime"].value == pytest.approx(0.13, rel=1e-3) and not e["T_q0_prime"].identifiable


def test_bounds_around_the_estimate_change_nothing(scenarios, free) -> None:
    e = run(scenarios, bounds=["H=3:4", "X_d_prime=0.3:0.7", "T_d0_prime=1:2"]).estimates
    for name in ("H", "D", "X_d_prime", "T_d0_prime", "T_q0_prime"):
        assert e[name].value == pytest.approx(free[name].value, rel=1e-6) and e[name].identifiable


def test_the_paper_method_holds_and_starts(scenarios) -> None:
    e = run(scenarios, "paper", fix=["X_d_prime=0.5", "T_d0_prime=1.437"], start=["X_q_prime=0.8"]).estimates
    assert (e["X_d_prime"].value, e["T_d0_prime"].value) == (0.5, 1.437)
    assert abs(e["X_q_prime"].value / TRUTH["X_q_prime"] - 1) < 0.01
    assert abs(e["T_q0_prime"].value / TRUTH["T_q0_prime"] - 1) < 0.01


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"fix": ["Hx=3"]}, r"--fix 'Hx=3': unknown parameter 'Hx'"),
        ({"fix": ["H=99"]}, r"--fix: H=99 s lies outside its physical range \[0.5, 15\]"),
        ({"bounds": ["H=4:3"]}, r"--bounds H=4:3: LO must be below HI"),
        ({"bounds": ["H=3"]}, r"--bounds H=3: expected LO:HI"),
        ({"fix": ["H=3"], "bounds": ["H=2:4"]}, r"--bounds H: H is held by --fix"),
        ({"bounds": ["H=2:3"], "start": ["H=3.5"]}, r"--start H=3.5 lies outside its --bounds"),
        ({"fix": ["X_d=1", "X_d_prime=1.2"]}, r"X_d_prime=1.2 must be below X_d=1"),
    ],
)
def test_bad_constraints_are_named(kw, message) -> None:
    with pytest.raises(ParameterError, match=message):
        parse_constraints(**kw)


def test_the_datasheet_s_saturation() -> None:
    c = parse_constraints(saturation="0.1, 0.4")
    assert c.saturation == (0.1, 0.4) and c and c.as_dict()["saturation"] == {"S10": 0.1, "S12": 0.4}
    for bad, says in (("0.4,0.1", "needs S(1.2) > S(1.0) > 0"), ("0.1", "expected S10,S12"), ("a,0.4", "not a number")):
        with pytest.raises(ParameterError, match=re.escape(says)):
            parse_constraints(saturation=bad)
