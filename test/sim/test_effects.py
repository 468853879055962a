"""The plant effects library: registry, parameter ranges, and what each effect does to the plant."""

from dataclasses import replace

import numpy as np
import pytest

from phid_ros.errors import SimulationError
from phid_ros.sim.effects import REGISTRY, parse_effect
from phid_ros.sim.effects.magnetic_saturation import MagneticSaturation
from phid_ros.sim.effects.stator_resistance import StatorResistance
from phid_ros.sim.plant import OperatingPoint
from phid_ros.sim.runner import SimulationConfig, build_inputs, simulate_scenarios
from phid_ros.sim.scenarios import Scenario, find_scenario
from phid_ros.sim.sensors import SensorModel

NOISELESS = SimulationConfig(sensors=SensorModel(noiseless=True), restore_ramp=1.0, restore_hold=1.0)


def test_registry_and_the_simulate_syntax():
    assert set(REGISTRY) == {
        "stator_resistance",
        "magnetic_saturation",
        "sensor_delay",
        "subtransient_dynamics",
        "shaft_torsion",
    }
    # each effect is named after its module: the command line lists them from the modules' names
    from phid_ros.cli.parser import effect_names

    assert effect_names() == sorted(REGISTRY)
    assert all(cls.__module__ == f"phid_ros.sim.effects.{name}" for name, cls in REGISTRY.items())
    e = parse_effect("magnetic_saturation=s10=0.1,s12=0.4")
    assert isinstance(e, MagneticSaturation) and e["s10"] == 0.1 and e["s12"] == 0.4
    assert parse_effect("stator_resistance")["r_a"] == 0.005  # default
    with pytest.raises(SimulationError, match="unknown effect 'windage'; available: magnetic_saturation"):
        parse_effect("windage")
    with pytest.raises(SimulationError, match=r"r_a=0.5 pu outside \[0.001, 0.02\]"):
        parse_effect("stator_resistance=r_a=0.5")
    with pytest.raises(SimulationError, match="unknown parameter"):
        parse_effect("sensor_delay=lag=3")
    with pytest.raises(SimulationError, match="not one of"):
        parse_effect("sensor_delay=stream=gps")


@pytest.mark.parametrize(
    "effect",
    [
        StatorResistance(r_a=0.01),
        MagneticSaturation(s10=0.1, s12=0.4),
        parse_effect("subtransient_dynamics"),
        parse_effect("shaft_torsion"),
    ],
)
def test_initialisation_stays_an_equilibrium_with_the_effect(effect):
    cfg = replace(NOISELESS, effects=(effect,))
    plant = cfg.plant()
    ss = plant.steady_state(OperatingPoint())
    inputs = build_inputs([Scenario("quiet", "torque_step", 0.0, duration=2.0)], plant, ss, cfg)
    assert np.max(np.abs(plant.derivatives(ss.x[:, None], inputs))) < 1e-9


def test_saturation_needs_more_field_voltage_and_resistance_more_mechanical_power():
    base = SimulationConfig().plant().steady_state(OperatingPoint())
    sat = (
        replace(SimulationConfig(), effects=(MagneticSaturation(s10=0.1, s12=0.4),))
        .plant()
        .steady_state(OperatingPoint())
    )
    res = replace(SimulationConfig(), effects=(StatorResistance(r_a=0.01),)).plant().steady_state(OperatingPoint())
    assert sat.v_f > base.v_f * 1.02  # the saturated field needs more excitation
    i2 = res.i_d**2 + res.i_q**2
    assert res.p_m == pytest.approx(0.8 + 0.01 * i2, rel=1e-9)  # P_m covers the copper losses


def test_sensor_delay_shifts_one_stream_only():
    sc = replace(find_scenario("S14"), duration=3.0)
    plain = simulate_scenarios([sc], NOISELESS)[0]
    late = simulate_scenarios([sc], replace(NOISELESS, effects=(parse_effect("sensor_delay=stream=pmu,delay_ms=20"),)))[
        0
    ]
    assert np.array_equal(late.measured["delta"][20:], plain.measured["delta"][:-20])
    assert np.array_equal(late.measured["v_t"], plain.measured["v_t"])  # PT/CT untouched
    assert np.array_equal(late.truth["delta"], plain.truth["delta"])  # the plant itself is not delayed


def test_simulate_command_records_the_effects(tmp_path):
    import json

    from phid_ros.cli.main import main

    out = tmp_path / "sat.mcap"
    assert (
        main(
            [
                "simulate",
                "--scenario",
                "S09",
                "--duration",
                "3",
                "--effect",
                "magnetic_saturation=s10=0.1",
                "--effect",
                "sensor_delay",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    truth = json.loads((tmp_path / "sat.mcap.truth.json").read_text())
    assert [e["name"] for e in truth["effects"]] == ["magnetic_saturation", "sensor_delay"]


def test_damper_windings_raise_the_first_cycle_fault_current():
    sc = replace(find_scenario("S14"), duration=3.0)
    base = simulate_scenarios([sc], NOISELESS)[0]
    sub = simulate_scenarios([sc], replace(NOISELESS, effects=(parse_effect("subtransient_dynamics"),)))[0]
    k = int(round(sc.t_event / 1e-3))
    i_base = np.hypot(base.truth["i_d"], base.truth["i_q"])[k]
    i_sub = np.hypot(sub.truth["i_d"], sub.truth["i_q"])[k]
    assert i_sub > 1.15 * i_base  # behind X'' instead of X'
    # and it decays to the transient behaviour within a few T''_d0
    assert (
        abs(
            np.hypot(sub.truth["i_d"], sub.truth["i_q"])[k + 120]
            / np.hypot(base.truth["i_d"], base.truth["i_q"])[k + 120]
            - 1
        )
        < 0.1
    )


def test_shaft_torsion_adds_its_mode_to_the_measured_speed():
    sc = replace(find_scenario("S14"), duration=3.0)
    run = simulate_scenarios([sc], replace(NOISELESS, effects=(parse_effect("shaft_torsion=f_torsion_hz=18"),)))[0]
    w = run.truth["omega"][1200:2200] - np.mean(run.truth["omega"][1200:2200])
    spectrum = np.abs(np.fft.rfft(w * np.hanning(len(w))))
    freqs = np.fft.rfftfreq(len(w), 1e-3)
    band = (freqs > 5) & (freqs < 40)
    assert abs(freqs[band][np.argmax(spectrum[band])] - 18.0) < 1.5


def test_truth_names_the_leakage_reactance_in_force():
    # Unset, X_l follows the planning rule min(0.15, 0.8 X''); the truth file must carry that
    # number (a "null" would leave a reader to guess which X_l the simulated machine had).
    from phid_ros.sim.effects import effects_summary
    from phid_ros.sim.effects.subtransient_dynamics import SubtransientDynamics

    unset = SubtransientDynamics(x_dpp=0.16, x_qpp=0.2)
    assert effects_summary([unset])[0]["x_l"] == pytest.approx(0.128)
    assert SubtransientDynamics(x_dpp=0.25, x_qpp=0.3).as_dict()["x_l"] == pytest.approx(0.15)
    assert SubtransientDynamics(x_l=0.1).as_dict()["x_l"] == pytest.approx(0.1)
