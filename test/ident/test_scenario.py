import numpy as np
import pytest

from phid_ros.ident.scenario import ScenarioError, classify, find_events, make_scenario


def test_classify_each_kind_from_the_signals(clean_scenarios):
    for sc in clean_scenarios:
        if sc.role != "identify":
            continue
        kind, k_ev, k_cl, reason = classify(sc.signals, sc.dt)
        assert kind == sc.kind, (sc.name, reason)
        assert abs(k_ev - sc.k_event) <= 5  # within 5 ms
        if kind == "fault":
            assert abs(k_cl - sc.k_clear) <= 5


def test_find_events_in_a_continuous_recording(short_recording):
    from phid_ros.stream.scenarios import aligned_channels

    t, dt, ch, _ = aligned_channels(short_recording, "test")
    events = find_events(ch, dt)
    for marker in short_recording.scenarios:
        hit = [e for e in events if abs(int(t[e[1]]) - marker.event_ns) <= 5_000_000]
        assert len(hit) == 1 and hit[0][0] == marker.kind, marker.name
        if marker.kind == "fault":
            assert abs(int(t[hit[0][2]]) - marker.clearing_ns) <= 5_000_000
    # anything else is the fixture's fast 1 s restore ramp, after a window's end
    for kind, k, _ in events:
        if not any(abs(int(t[k]) - m.event_ns) <= 5_000_000 for m in short_recording.scenarios):
            assert any(m.end_ns < int(t[k]) <= m.end_ns + 2_100_000_000 for m in short_recording.scenarios)


def test_windows_with_nan_or_too_short_are_refused(clean_scenarios):
    sc = clean_scenarios[3]
    sig = {k: v.copy() for k, v in sc.signals.items()}
    sig["i_q"][2500] = np.nan
    with pytest.raises(ScenarioError, match=r"channel i_q has 1 NaN/Inf sample\(s\), first at t = 2.500 s"):
        make_scenario("x", sig, sc.dt, kind=sc.kind, k_event=sc.k_event)
    with pytest.raises(ScenarioError, match="too short"):
        make_scenario("x", {k: v[:500] for k, v in sc.signals.items()}, sc.dt, kind=sc.kind, k_event=100)


def test_no_disturbance_is_said(clean_scenarios):
    quiet = {k: np.full(3000, v[0]) for k, v in clean_scenarios[0].signals.items()}
    with pytest.raises(ScenarioError, match="no disturbance found"):
        make_scenario("quiet", quiet, 1e-3)


def test_voltage_components_use_the_internal_angle(clean_scenarios):
    sc = clean_scenarios[0]
    ang = sc["delta"] - sc["theta_t"]
    assert np.allclose(sc.v_d, sc["v_t"] * np.sin(ang)) and np.allclose(sc.v_q, sc["v_t"] * np.cos(ang))
