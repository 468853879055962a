from pathlib import Path

import pytest

from phid_ros.ident import ieee115
from phid_ros.ident.validation import validate
from phid_ros.model.parameters import TABLE1


def test_ieee115_baseline_runs_and_flags_its_bounds(noisy_scenarios):
    b = ieee115.identify(noisy_scenarios, TABLE1.X_d, TABLE1.X_q)
    est = b.estimates()
    assert set(est) == {"X_d_prime", "T_d0_prime", "X_q_prime", "T_q0_prime"}
    # (16)-(17): open-circuit from short-circuit time constants
    assert est["T_d0_prime"].value == pytest.approx(b.d.t_short * b.d.x_sync / b.d.x_prime)
    # on short faults of a loaded machine the envelope method runs into its own bounds
    assert any(e.at_bound for e in est.values())
    assert len(b.scenarios) == 4


def test_ieee115_needs_faults(noisy_scenarios):
    with pytest.raises(ieee115.BaselineError, match="needs fault scenarios"):
        ieee115.identify([s for s in noisy_scenarios if s.kind != "fault"], 2.5, 2.4)


def test_validation_of_the_truth_against_itself_is_zero(clean_scenarios):
    primary, measured = validate(clean_scenarios, TABLE1, TABLE1)
    assert [m.scenario for m in primary.scenarios] == ["V1_power_step", "V2_voltage_dip", "V3_fault_150ms"]
    assert all(m.rms_delta_deg == 0.0 and m.rmse == 0.0 for m in primary.scenarios)
    # and the play-in of the true model follows the (noise-free) plant closely; what is left is
    # the fault's switching instant, which sampled inputs place within half a play-in step
    assert all(m.rms_delta_deg < 0.06 and m.rms_omega_pct < 0.003 and m.mod026_pass for m in measured.scenarios)
    assert measured.scenarios[0].rms_delta_deg < 0.01  # no switching: near-exact


def test_validation_separates_good_and_bad_parameters(noisy_scenarios):
    close = TABLE1.replace(X_d_prime=0.502, T_q0_prime=0.136)
    far = TABLE1.replace(X_d_prime=0.6, X_q_prime=1.1, T_d0_prime=3.0, T_q0_prime=0.1)
    good, _ = validate(noisy_scenarios, close, TABLE1)
    bad, _ = validate(noisy_scenarios, far, TABLE1)
    assert good.worst("rms_delta_deg") < 0.2 and good.worst("rms_omega_pct") < 0.02
    assert bad.worst("rms_delta_deg") > 5 * good.worst("rms_delta_deg")


def test_a_model_that_fails_mod026_on_every_validation_event_is_not_published_as_identified():
    """bags/saturation: the fourth-order model misses the machine's saturation and every
    validation event's P or Q misses by more than 0.05 pu; its small std did not stop it being
    published before (X_d +42 % identified on a salient-pole machine). Withheld now, with why."""
    from phid_ros.api import identify_recording, load_recording
    from phid_ros.ident.pipeline import IdentifyOptions

    bags = Path(__file__).resolve().parents[2] / "bags"
    rec = load_recording(bags / "saturation")
    _, res = identify_recording(rec, "saturation", IdentifyOptions(baseline=False))
    assert res.validation is not None and not any(s.mod026_pass for s in res.validation.scenarios)
    assert not any(e.identifiable for e in res.estimates.values())
    assert all("fails MOD-026 on every validation event" in e.note for e in res.estimates.values())
    assert any("the model structure is insufficient, run phid diagnose" in p for p in res.problems)
    # the catalogue's model passes and keeps its parameters
    _, ok = identify_recording(load_recording(bags / "catalogue"), "catalogue", IdentifyOptions(baseline=False))
    assert ok.validation is not None and all(s.mod026_pass for s in ok.validation.scenarios)
    assert ok.estimates["X_d"].identifiable and "MOD-026" not in ok.estimates["X_d"].note
