import pytest

from phid_ros.ident.stage1 import Stage1Error, differential_damping, swing_regression
from phid_ros.model.parameters import TABLE1


def test_swing_regression_is_exact_on_clean_data(clean_scenarios):
    r = swing_regression(clean_scenarios)
    assert r.H.value == pytest.approx(TABLE1.H, rel=2e-4)
    assert r.D.value == pytest.approx(TABLE1.D, rel=2e-3)


def test_swing_regression_with_sensor_noise(noisy_scenarios):
    r = swing_regression(noisy_scenarios)
    assert r.H.value == pytest.approx(TABLE1.H, rel=2e-3)
    # D is small next to the synchronising power: P sensor noise limits it to a few %,
    # and the reported standard deviation must say so honestly
    assert abs(r.D.value - TABLE1.D) < 3 * r.D.std
    assert 0.005 < r.D.std < 0.04
    assert r.D.drivers and all(name.startswith("S1") for name in r.D.drivers)  # faults carry D


def test_without_the_switching_terms_d_is_biased(clean_scenarios, monkeypatch):
    """The half-sample ambiguity of a sampled fault is what the impulse terms absorb."""
    import phid_ros.ident.stage1 as s1

    class NoSwitch:
        def __init__(self, sc):
            self._sc = sc

        def __getattr__(self, name):
            return [] if name == "switching" else getattr(self._sc, name)

        def __getitem__(self, k):
            return self._sc[k]

    faults = [NoSwitch(s) for s in clean_scenarios if s.kind == "fault"]
    biased = s1.swing_regression(faults)
    assert abs(biased.D.value - TABLE1.D) > 0.05


def test_paper_differential_damping_runs_on_pairs(clean_scenarios):
    r = differential_damping(clean_scenarios)
    assert r.H.value == pytest.approx(TABLE1.H, rel=0.01)
    assert len(r.details["pairs"]) == 2
    assert r.D.value > 0


def test_stage1_says_what_is_missing(clean_scenarios):
    dampingless = [s for s in clean_scenarios if not s.generator_damping]
    with pytest.raises(Stage1Error, match="every scenario is dampingless"):
        swing_regression(dampingless)
    normal_only = [s for s in clean_scenarios if s.generator_damping]
    with pytest.raises(Stage1Error, match="needs dampingless torque scenarios"):
        differential_damping(normal_only)
