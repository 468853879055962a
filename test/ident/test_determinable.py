"""Recordings with a recorder's channels: what they determine comes back, the rest is named.

The recordings are the project's simulator written as real recorders write them
(:mod:`test.io.field.field_sets`): an excitation controller's trend logs (V_t, P, Q, I_t, E_fd, I_fd
on its own bases, ~208 reports/s with jitter, a no-load test on one day and on-line steps on
the next) and PMU exports (V and I phasors only).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from phid_ros.api import identify_recording
from phid_ros.errors import PhidError
from phid_ros.ident import determinable, open_circuit, terminal
from phid_ros.ident.constraints import Constraints
from phid_ros.ident.pipeline import IdentifyOptions
from phid_ros.ident.scenario import make_scenario, scenario_from_simulation
from phid_ros.io.field.channel_map import ChannelMapError, load_channel_map
from phid_ros.io.field.pmu_csv import import_pmu_csv
from phid_ros.model.channels import CHANNEL_INDEX, Frame
from phid_ros.model.conventions import utc_of_stamp
from phid_ros.model.parameters import TABLE1
from phid_ros.sim.runner import simulate_scenarios
from phid_ros.sim.scenarios import Scenario
from test.io.field.field_sets import FIELD_BASE_A, FIELD_BASE_V, NO_LOAD, pmu_set, trend_log_set

NOT_DETERMINED = "not identifiable from these channels"


def _identify(rec, **fixed):
    _, res = identify_recording(rec, "set", IdentifyOptions(constraints=Constraints(fixed=fixed), validate=False))
    return res


@pytest.fixture(scope="module")
def trend(tmp_path_factory):
    folder = tmp_path_factory.mktemp("trend")
    paths, cmap = trend_log_set(folder, TABLE1)
    return import_pmu_csv(paths, load_channel_map(cmap))


@pytest.fixture(scope="module")
def pmu(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pmu")
    paths, cmap = pmu_set(folder, TABLE1)
    return import_pmu_csv(paths, load_channel_map(cmap))


def test_trend_logs_calibrate_the_field_base_at_no_load(trend) -> None:
    def base(prefix: str) -> float:
        note = next(w for w in trend.warnings if w.startswith(prefix))
        return float(note.split("1 pu = ")[1].split(" ")[0])

    assert base("v_f (UF): 1 pu = ") == pytest.approx(FIELD_BASE_V, rel=1e-3)
    assert base("i_fd (IF): 1 pu = ") == pytest.approx(FIELD_BASE_A, rel=1e-3)
    # the scenarios lie one after another; no rotor angle, speed or P_m was recorded
    assert [s.name for s in trend.scenarios][:2] == ["noload", "step_0"]
    assert np.isnan(trend.streams["encoder"].channels["omega"]).all()
    # the set begins when its first file's date and time of day say
    assert utc_of_stamp(trend.span_ns()[0]).isoformat().startswith("2015-09-20T12:52:35.236")


def test_d_axis_from_voltage_steps_and_a_no_load_step(trend) -> None:
    res = _identify(trend, X_q=TABLE1.X_q)  # the datasheet's X_q for the rotor angle
    e = res.estimates
    assert e["X_d"].identifiable and e["X_d"].value == pytest.approx(TABLE1.X_d, rel=0.01)
    assert e["T_d0_prime"].identifiable and e["T_d0_prime"].value == pytest.approx(TABLE1.T_d0_prime, rel=0.01)
    assert res.determined_by["T_d0_prime"].startswith("no-load field steps")
    xdp = e["X_d_prime"]  # -2 % to 0 over four noise seeds
    assert xdp.identifiable and xdp.value == pytest.approx(TABLE1.X_d_prime, rel=0.03)
    for name in ("H", "D", "X_q_prime", "T_q0_prime"):
        assert math.isnan(e[name].value) and not e[name].identifiable, name
        assert NOT_DETERMINED in e[name].note, name
    assert "omega" in e["H"].note and "delta" in e["X_q_prime"].note


def test_without_a_datasheet_x_q_it_is_withheld_and_x_d_still_comes_back(trend) -> None:
    res = _identify(trend)
    e = res.estimates
    assert math.isnan(e["X_q"].value) and "not identifiable from V_t, P, Q, E_fd" in e["X_q"].note
    assert e["X_d"].value == pytest.approx(TABLE1.X_d, rel=0.01)
    xdp = e["X_d_prime"]
    # its error bar carries what +-10 % of X_q does to it
    assert "for X_q +-10 %" in xdp.note or not xdp.identifiable
    assert not xdp.identifiable or xdp.value == pytest.approx(TABLE1.X_d_prime, rel=0.03)


def test_h_from_pmu_swings_with_p_m_constant(pmu) -> None:
    res = _identify(pmu, X_q=TABLE1.X_q, X_q_prime=TABLE1.X_q_prime, T_q0_prime=TABLE1.T_q0_prime)
    e = res.estimates
    assert e["H"].identifiable and e["H"].value == pytest.approx(TABLE1.H, rel=0.03)
    assert "P_m constant between steps" in res.determined_by["H"]
    assert not e["D"].identifiable  # a few percent of the damping, too little in five swings
    for name in ("X_d", "X_d_prime", "T_d0_prime"):
        assert math.isnan(e[name].value) and NOT_DETERMINED in e[name].note, name
    # a salient-pole reconstruction (X_q held alone) still gives H within 3 % on this round rotor
    assert _identify(pmu, X_q=TABLE1.X_q).estimates["H"].value == pytest.approx(TABLE1.H, rel=0.03)


def test_pmu_without_a_held_x_q_identifies_nothing_and_says_what_is_missing(pmu) -> None:
    with pytest.raises(PhidError, match=r"nothing identified: .*H: not identifiable from these channels \(needs omega"):
        _identify(pmu)


def _blanked(run, signals, *channels):
    s = scenario_from_simulation(run, signals)
    values = np.array(s.frame.values, order="F")
    for c in channels:
        values[:, CHANNEL_INDEX[c]] = np.nan
    return make_scenario(s.name, Frame(s.frame.t_ns, values, s.frame.period_ns), kind=s.kind, k_event=s.k_event)


def test_the_rotor_angle_from_the_terminal_quantities() -> None:
    [run] = simulate_scenarios([Scenario("F", "field_step", 1.1, duration=6.0)])
    s = _blanked(run, run.truth, "delta", "i_d", "i_q", "omega", "p_m")
    assert s.absent == {"delta", "i_d", "i_q", "omega", "p_m"}
    true_load = run.truth["delta"][: s.n] - run.truth["theta_t"][: s.n]
    static = terminal.with_rotor_angle(s, TABLE1.X_q, "test")
    follow = terminal.with_rotor_angle(s, TABLE1.X_q, "test", (TABLE1.X_q_prime, TABLE1.T_q0_prime))
    err = lambda r: np.abs(r["delta"] - r["theta_t"] - true_load)  # noqa: E731
    assert err(static)[: s.k_event].max() < 1e-9  # at rest the phasor diagram is exact
    assert err(static).max() > 1e-3  # a round rotor's q flux lags through the step ...
    assert err(follow).max() < 2e-4  # ... and following it with (8) puts the rotor back
    assert static.absent == {"omega", "p_m"} and "rotor angle reconstructed" in static.notes[-1]


def test_t_d0_from_a_no_load_step() -> None:
    runs = simulate_scenarios([Scenario("NL", "field_step", 1.1, duration=12.0)], NO_LOAD)
    s = _blanked(runs[0], runs[0].measured, "delta", "i_d", "i_q", "omega", "p_m", "theta_t")
    assert terminal.at_no_load(s)
    r = open_circuit.open_circuit([s])
    assert r.T_d0_prime.value == pytest.approx(TABLE1.T_d0_prime, rel=0.01) and r.T_d0_prime.identifiable
    assert r.field_gain == pytest.approx(1.0, abs=2e-3)
    plan = {p.parameter: p for p in determinable.plan([s], {})}
    assert plan["T_d0_prime"].route.key == "open_circuit" and plan["X_d"].route is None


def test_field_quantities_in_volts_need_a_base_or_a_no_load_test(tmp_path) -> None:
    paths, cmap = trend_log_set(tmp_path, TABLE1)
    with pytest.raises(ChannelMapError, match=r"v_f \(UF\) is recorded in V without a base, and no no-load test"):
        import_pmu_csv(paths[1:], load_channel_map(cmap))
    text = cmap.read_text()
    cmap.write_text(  # a stated base for E_fd, and no I_fd mapped: the on-line tests alone import
        text.replace("{name: UF, unit: V}", f"{{name: UF, unit: V, base: {FIELD_BASE_V}}}").replace(
            "  i_fd: {name: IF, unit: A}\n", ""
        )
    )
    rec = import_pmu_csv(paths[1:], load_channel_map(cmap))
    v_f = rec.streams["excitation"].channels["v_f"]
    assert np.mean(v_f[:100]) == pytest.approx(run_v_f(), rel=2e-3)
    # a CT ratio wrong by 10 %: I_t and |P + jQ| / V_t disagree, named
    cmap.write_text(text.replace("{name: IT, unit: A}", "{name: IT, unit: A, side: secondary}") + "ratios: {ct: 1.1}\n")
    with pytest.raises(ChannelMapError, match=r"I_t is 1\.1 times \|P \+ jQ\| / V_t"):
        import_pmu_csv(paths, load_channel_map(cmap))


def run_v_f() -> float:
    """The on-line operating point's field voltage, per unit."""
    return float(simulate_scenarios([Scenario("x", "field_step", 1.0001, duration=2.0)])[0].truth["v_f"][0])


def test_several_recordings_of_one_unit_in_one_identification(tmp_path) -> None:
    from phid_ros.api import identify_recordings

    paths, cmap = trend_log_set(tmp_path, TABLE1)
    no_load = import_pmu_csv(paths[:1], load_channel_map(cmap))  # the no-load test calibrates its own base
    stated = tmp_path / "stated.yaml"  # the next day's import states the base the no-load test gave
    stated.write_text(
        cmap.read_text()
        .replace("{name: UF, unit: V}", f"{{name: UF, unit: V, base: {FIELD_BASE_V}}}")
        .replace("{name: IF, unit: A}", "{name: IF, unit: A, base: 1876}")
    )
    online = import_pmu_csv(paths[1:], load_channel_map(stated))
    options = IdentifyOptions(constraints=Constraints(fixed={"X_q": TABLE1.X_q}), validate=False)
    scenarios, res = identify_recordings([(no_load, "day1.mcap"), (online, "day2.mcap")], options)
    assert [s.name for s in scenarios][:2] == ["day1/noload", "day2/step_0"]
    e = res.estimates
    assert e["T_d0_prime"].value == pytest.approx(TABLE1.T_d0_prime, rel=0.01)
    assert e["X_d"].value == pytest.approx(TABLE1.X_d, rel=0.01)
    assert e["X_d_prime"].value == pytest.approx(TABLE1.X_d_prime, rel=0.03)


def test_recorders_at_different_rates_meet_on_the_coarsest_grid() -> None:
    from phid_ros.ident.scenario import on_one_grid

    [run] = simulate_scenarios([Scenario("F", "field_step", 1.1, duration=4.0)])
    fast = scenario_from_simulation(run, run.truth)
    period = 4_807_692  # 208 reports per second
    slow = fast.with_frame(fast.frame)
    slow.name = "slow"
    both, notes = on_one_grid([fast, slow.rows(0, slow.n)])
    assert not notes  # one rate: nothing to do
    coarse = make_scenario(
        "coarse",
        Frame.of_columns({c: x[::5] for c, x in fast.frame.columns().items()}, period),
        kind="field_step",
        k_event=208,
    )
    both, notes = on_one_grid([fast, coarse])
    assert [s.frame.period_ns for s in both] == [period, period] and "1 scenario(s) resampled" in notes[0]
    got = both[0]
    assert got.k_event == round(fast.k_event * 1e6 / period)
    t = np.arange(got.n) * period / 1e9
    # away from the step (the low-pass rings there), the channels are the simulator's
    ok = np.abs(t - 1.0) > 0.1
    assert np.max(np.abs(got["v_t"] - np.interp(t, np.arange(fast.n) * 1e-3, fast["v_t"]))[ok]) < 2e-4
