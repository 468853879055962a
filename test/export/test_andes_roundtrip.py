"""The exported record in a simulator no one here wrote: ANDES, single machine on an infinite bus.

The case is the one phid's own simulator uses (phid_ros.sim: 0.12 + 0.08 pu to the infinite bus,
P = 0.8, Q = 0.4 at V_t = 1.0, 1000 MVA machine on ANDES's 100 MVA system base). The .dyr goes
through ANDES's PSS/E reader, the ANDES JSON through its JSON reader; a torque step of 0.1 pu and
a 100 ms terminal fault through 0.04 pu are simulated in both and delta, omega compared.

GENROU reduces exactly to the paper's fourth-order model when X'_d = X'_q = X'' (both dampers
inert): there the two simulators must agree to integration error. Where X'_d != X'_q, GENROU
keeps a q-axis damper (X'' = X'_d, T''_q0 = 0.03 s default): the difference is measured here and
quoted in the README.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from phid_ros.export.formats import andes_json, psse_dyr
from phid_ros.export.record import MachineRecord, build_record
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1, GeneratorParameters
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import Scenario
from test.andes_plant import MACHINE_MVA, run, system

# per test, not at module level: pytest 7 (the ROS tier's) skips the whole package for a module-level skip
pytestmark = pytest.mark.usefixtures("andes_available")


@pytest.fixture
def andes_available() -> None:
    pytest.importorskip("andes")


DURATION_S = 10.0
TORQUE_STEP = Scenario("T", "torque_step", 0.1, duration=DURATION_S)
FAULT = Scenario("F", "fault", 0.1, duration=DURATION_S)


def export(params: GeneratorParameters) -> MachineRecord:
    result = {
        "parameters": params.as_dict(),
        "identifiable": {n: True for n in PARAMETER_NAMES},
        "f_nominal_hz": 50.0,
    }
    return build_record(result, source="result.json", mva=MACHINE_MVA, bus=1, machine_id="1")


def andes_run(record_file: Path, fmt: str, scenario: Scenario, cfg: SimulationConfig) -> tuple[np.ndarray, ...]:
    if fmt == "psse-dyr":
        s = system(dyr=record_file, cfg=cfg)
    else:
        s = system(cfg=cfg)
        import andes

        andes.io.json.read(s, str(record_file))
    assert s.GENROU.n == 1
    ch = run(s, scenario, dt=0.01)  # ANDES's trapezoidal rule at 10 ms: 0.002 deg against phid (below)
    return ch["t"], ch["delta"], ch["omega"]


def compare(tmp_path: Path, params: GeneratorParameters, fmt: str, scenario: Scenario) -> tuple[float, float]:
    """RMS of (delta - delta_0) in degrees and of omega in pu, ANDES against phid over the scenario."""
    rec = export(params)
    path = tmp_path / ("unit.dyr" if fmt == "psse-dyr" else "unit.json")
    path.write_text(psse_dyr(rec) if fmt == "psse-dyr" else andes_json(rec))
    cfg = SimulationConfig(params=params)
    t_a, d_a, w_a = andes_run(path, fmt, scenario, cfg)
    run = simulate_scenarios([scenario], cfg)[0]
    n = run.n_analysis
    t, d, w = run.t[:n], run.states["delta"][:n], run.states["omega"][:n]
    assert abs(d_a[0] - d[0]) < 1e-5  # the same operating point, the same angle reference
    d_i, w_i = np.interp(t, t_a, d_a), np.interp(t, t_a, w_a)
    e_delta = np.degrees((d_i - d_i[0]) - (d - d[0]))
    return float(np.sqrt(np.mean(e_delta**2))), float(np.sqrt(np.mean((w_i - w) ** 2)))


@pytest.mark.parametrize(
    ("fmt", "scenario"), [("psse-dyr", TORQUE_STEP), ("andes", FAULT)], ids=["dyr-torque_step", "andes-fault"]
)
def test_genrou_record_reproduces_the_fourth_order_model(tmp_path: Path, fmt: str, scenario: Scenario) -> None:
    # measured 0.002 deg (torque step) and 0.007 deg (fault): ANDES's trapezoidal rule at 10 ms
    rms_delta, rms_omega = compare(tmp_path, TABLE1.replace(X_q_prime=TABLE1.X_d_prime), fmt, scenario)
    assert rms_delta < 0.02 and rms_omega < 1e-5, (rms_delta, rms_omega)


def test_table1_machine_torque_step_within_a_tenth_of_a_degree(tmp_path: Path) -> None:
    # X'_q = 0.814 > X'_d = 0.5: GENROU's q-axis damper (default T''_q0 = 0.02 s) stays, the q axis
    # written through it; measured 0.005 deg (0.045 before, the fourth-order X'_q, T'_q0 written as they are)
    rms_delta, _ = compare(tmp_path, TABLE1, "psse-dyr", TORQUE_STEP)
    assert rms_delta < 0.02, rms_delta


def test_table1_machine_fault_is_played_through_the_q_axis_damper(tmp_path: Path) -> None:
    # during a terminal fault the q-axis damper GENROU cannot leave out shows, small once the q axis
    # is written as the classical constants that play the identified X'_q, T'_q0 through it
    # (phid_ros.model.damper_equivalent): measured 0.042 deg RMS, where writing the fourth-order
    # values as GENROU's gave 0.32 deg
    rms_delta, _ = compare(tmp_path, TABLE1, "psse-dyr", FAULT)
    assert rms_delta < 0.1, rms_delta


def unit_record(params: GeneratorParameters, controls: dict) -> MachineRecord:
    """The record ``phid export`` writes of an identification with every machine parameter and
    these ``controls`` (identify's JSON form)."""
    result = {
        "parameters": params.as_dict(),
        "identifiable": {n: True for n in PARAMETER_NAMES},
        "f_nominal_hz": 50.0,
        "controls": controls,
    }
    return build_record(result, source="result.json", mva=MACHINE_MVA, bus=1, machine_id="1")


def loaded(tmp_path: Path, rec: MachineRecord, fmt: str, cfg: SimulationConfig):
    """ANDES's single-machine case with the record written in ``fmt`` and read by ANDES's own
    reader for it (its PSS/E .dyr reader, or its JSON reader)."""
    path = tmp_path / ("unit.dyr" if fmt == "psse-dyr" else "unit.json")
    path.write_text(psse_dyr(rec) if fmt == "psse-dyr" else andes_json(rec))
    if fmt == "psse-dyr":
        return system(dyr=path, cfg=cfg)
    import andes

    s = system(cfg=cfg)
    andes.io.json.read(s, str(path))
    return s


CONTROLS = {
    "exciter": {
        "model": "SEXS",
        "parameters": {"TA/TB": 0.2, "TB": 5.0, "K": 100.0, "TE": 0.05, "EMIN": None, "EMAX": None},
        "identifiable": {"TA/TB": True, "TB": True, "K": True, "TE": True, "EMIN": False, "EMAX": False},
    },
    "governor": {
        "model": "TGOV1",
        "parameters": {"R": 0.05, "T1": 0.5, "VMAX": None, "VMIN": None, "T2": 2.0, "T3": 6.0, "Dt": 0.0},
        "identifiable": {"R": True, "T1": True, "VMAX": False, "VMIN": False, "T2": True, "T3": True, "Dt": False},
    },
}


def test_the_exciter_and_governor_go_out_beside_the_machine_in_both_formats(tmp_path: Path) -> None:
    """identify's ``controls`` exported with the machine: ANDES's PSS/E reader and its JSON reader
    take the same unit (SEXS, TGOV1 wired to the GENROU), and a fault in each simulates the same;
    the field voltage goes to its ceiling (the stated default EMAX) and back."""
    params = TABLE1.replace(X_q_prime=TABLE1.X_d_prime)
    rec = unit_record(params, CONTROLS)
    assert [c.model for c in rec.controls] == ["SEXS", "TGOV1"]
    assert rec.controls[0].sources["EMAX"].startswith("default") and rec.controls[1].sources["Dt"].startswith("default")
    runs = {}
    for fmt in ("psse-dyr", "andes"):
        s = loaded(tmp_path, rec, fmt, SimulationConfig(params=params))
        assert (s.GENROU.n, s.SEXS.n, s.TGOV1.n) == (1, 1, 1)
        assert (s.SEXS.K.v[0], s.SEXS.TE.v[0], s.TGOV1.R.v[0], s.TGOV1.T3.v[0]) == (100.0, 0.05, 0.05, 6.0)
        runs[fmt] = run(s, FAULT, dt=0.01)
    a, b = runs["psse-dyr"], runs["andes"]
    for c in ("delta", "omega", "v_f", "p_m"):
        assert np.allclose(a[c], b[c], atol=1e-6), c
    assert a["v_f"].max() == pytest.approx(5.0)  # the ceiling during the fault
    assert abs(a["v_f"][-1] - a["v_f"][0]) < 0.05 and abs(a["p_m"][-1] - a["p_m"][0]) < 0.01  # settled back


def test_a_unit_identified_from_its_staged_tests_exported_and_simulated_in_andes_reproduces_them(
    tmp_path: Path,
) -> None:
    """The whole round trip with all three records: ANDES's GENROU + SEXS + TGOV1 recorded through
    staged tests; phid identifies the exciter and the governor from the recordings; ``phid export``
    writes the unit's .dyr; ANDES simulates the exported unit through the same tests, and each
    MOD-026/027 channel stays within the validation's band of the recording. (The machine is
    taken as identified: its three stages need the paper's catalogue, which the independent-plant
    studies run; TGOV1's lags are not determined by one load-reference step, so the record is
    written with --allow-flagged, as a user would, and still reproduces the tests.)"""
    from phid_ros.cli.common import read_input
    from phid_ros.controls.identify import controls_json, identify_controls
    from phid_ros.controls.unit_validation import CHANNELS, channel_check
    from phid_ros.ident.validation import play_in_stride
    from phid_ros.stream.scenarios import scenarios_from_recording
    from test.andes_plant import STAGED_TESTS, run_unit, write_staged_unit

    _dyr, manifest = write_staged_unit(tmp_path / "staged")
    recording, source = read_input(manifest)
    scenarios, _ = scenarios_from_recording(recording, source)
    found = identify_controls(scenarios)
    assert {k: (f.model, f.named) for k, f in found.items() if not isinstance(f, str)} == {
        "exciter": ("SEXS", True),
        "governor": ("TGOV1", True),
    }
    machine = TABLE1.replace(X_q_prime=TABLE1.X_d_prime, D=0.8)  # PSS/E's D 0 at P_m0 0.8
    result = {
        "parameters": machine.as_dict(),
        "identifiable": {n: True for n in PARAMETER_NAMES},
        "f_nominal_hz": 50.0,
        "operating_point": {"p_m_pu": 0.8},
        "controls": controls_json(found),
    }
    rec = build_record(result, source="unit.json", mva=MACHINE_MVA, bus=1, machine_id="1", allow_flagged=True)
    assert [c.model for c in rec.controls] == ["SEXS", "TGOV1"]
    exported = tmp_path / "exported.dyr"
    exported.write_text(psse_dyr(rec))
    for sc, s in zip(STAGED_TESTS, scenarios, strict=True):
        assert s.name == sc.name
        ch = run_unit(exported, sc)
        idx = np.arange(0, s.n, play_in_stride(s.dt))
        pre = slice(0, int(np.searchsorted(idx, s.k_event)))
        for channel in CHANNELS:
            full = ch[channel] if channel in ("v_f", "p_m") else None
            at = None if full is not None else ch[channel][idx]
            check, _, _ = channel_check(channel, s[channel], s.dt, idx, pre, full, at)
            assert check.passed, (sc.name, channel, check)


def test_a_stabiliser_goes_out_with_its_exciter_and_andes_plays_it_as_phid_does(tmp_path: Path) -> None:
    """IEEEST on the electrical power, exported beside the machine and SEXS: ANDES's PSS/E reader
    and its JSON reader take the same unit (the stabiliser wired to the exciter), and through a
    torque step ANDES's stabiliser output equals phid's IEEEST fed ANDES's own electrical power
    (the two implementations of one block diagram), to 1 % of its peak."""
    from phid_ros.controls.models import IEEEST, ControlInputs

    params = TABLE1.replace(X_q_prime=TABLE1.X_d_prime)
    stabiliser = {"T1": 0.0, "T2": 0.02, "T3": 0.2, "T4": 0.04, "T6": 2.0, "KS": -0.2}
    pss = IEEEST().completed({**IEEEST().defaults(), **stabiliser})
    controls = {
        "exciter": CONTROLS["exciter"],
        "stabiliser": {
            "model": "IEEEST",
            "parameters": {**pss, "LSMAX": None, "LSMIN": None},
            "identifiable": {n: n in stabiliser and n != "T1" for n in pss},
        },
    }
    rec = unit_record(params, controls)
    assert [c.model for c in rec.controls] == ["SEXS", "IEEEST"]
    dyr = psse_dyr(rec)
    assert "1 'IEEEST' '1' 3 0 0 0 0 0 0 0 0 0.02 0.2 0.04 2 2 -0.2 0.1 -0.1 0 0 /" in dyr, dyr
    runs, vsout = {}, {}
    for fmt in ("psse-dyr", "andes"):
        s = loaded(tmp_path, rec, fmt, SimulationConfig(params=params))
        assert (s.GENROU.n, s.SEXS.n, s.IEEEST.n) == (1, 1, 1)
        runs[fmt] = run(s, TORQUE_STEP, dt=0.01)
        ts = s.dae.ts
        vsout[fmt] = np.interp(runs[fmt]["t"], ts.t, ts.y[:, s.IEEEST.vsout.a[0]])
    a = runs["psse-dyr"]
    assert np.allclose(vsout["psse-dyr"], vsout["andes"], atol=1e-9)
    peak = float(np.max(np.abs(vsout["andes"])))
    assert peak > 0.005  # the torque step moved the stabiliser
    x = ControlInputs(
        0.01, np.zeros(len(a["t"])), np.zeros(len(a["t"])), np.zeros(len(a["t"])), p_e=a["p_e"] - a["p_e"][0]
    )
    mine = IEEEST().response(pss, x, 0.0)
    err = float(np.max(np.abs(mine - vsout["andes"])))
    assert err < 0.01 * peak, err


def test_a_static_exciter_at_its_input_limit_goes_out_and_andes_plays_it_as_phid_does(tmp_path: Path) -> None:
    """EXST1 with the input limit ANDES's own EXST1 ships (VIMAX/VIMIN ±0.1) exported beside the
    machine: ANDES's PSS/E reader and its JSON reader take the same unit, and through a terminal
    fault through 0.3 pu (V_t down to about 0.6 pu: the error capped at 0.1) ANDES's field voltage
    equals phid's EXST1
    played through its limits on ANDES's own terminal voltage, to 3 % of its swing. The ceiling is
    set out of reach: ANDES's is V_RMAX - K_C I_FD, PSS/E's and phid's V_T V_RMAX - K_C I_FD
    (IEEE 421.5's ST1A), so a record whose ceiling binds with V_T away from 1 plays apart (V_RMAX 20
    in the fault through 0.04 pu: V_T fell to 0.19, phid's ceiling to 3.9 and ANDES's E_fd went to
    4.8, 0.83 pu apart)."""
    from phid_ros.controls.models import EXST1, ControlInputs, OperatingLevels

    DIP = Scenario("dip", "fault", 0.1, duration=DURATION_S, fault_reactance=0.3)
    params = TABLE1.replace(X_q_prime=TABLE1.X_d_prime)
    exciter = {"TR": 0.02, "VIMAX": 0.1, "VIMIN": -0.1, "TC": 1.0, "TB": 10.0, "KA": 200.0, "TA": 0.02}
    exciter |= {"VRMAX": 20.0, "VRMIN": -20.0, "KC": 0.0, "KF": 0.0, "TF": 1.0}
    controls = {
        "exciter": {
            "model": "EXST1",
            "parameters": exciter,
            "identifiable": dict.fromkeys(exciter, True),
        },
    }
    rec = unit_record(params, controls)
    assert [c.model for c in rec.controls] == ["EXST1"]
    runs = {}
    for fmt in ("psse-dyr", "andes"):
        s = loaded(tmp_path, rec, fmt, SimulationConfig(params=params))
        assert (s.GENROU.n, s.EXST1.n) == (1, 1)
        assert (s.EXST1.VIMAX.v[0], s.EXST1.KA.v[0], s.EXST1.VRMAX.v[0]) == (0.1, 200.0, 20.0)
        runs[fmt] = run(s, DIP, dt=0.002)
    a, b = runs["psse-dyr"], runs["andes"]
    assert np.allclose(a["v_f"], b["v_f"], atol=1e-6)
    t, v_t = a["t"], a["v_t"]
    x = ControlInputs(0.002, v_t - v_t[0], np.zeros(len(t)), np.zeros(len(t)))
    values = EXST1().completed({**EXST1().defaults(), **exciter})
    mine = a["v_f"][0] + EXST1().limited(values, x, 0.0, OperatingLevels(v_t, float(a["v_f"][0]), float(a["v_f"][0])))
    swing = float(np.max(a["v_f"]) - a["v_f"][0])
    # the input limit bound: the uncapped error (1 - V_t ~ 0.7 pu in the fault) would have driven E_fd
    # far higher through K_A T_C/T_B = 20
    assert swing > 1.0 and float(np.min(v_t)) < 0.7
    # the two integrations meet each switching (the fault's, its clearing's) a step apart: on E_fd's
    # 30 pu/s rise that step is 0.06 pu, so the 20 ms after each are left out (validate leaves
    # three cycles out)
    switched = (np.abs(t - DIP.t_event) < 0.02) | (np.abs(t - DIP.t_event - DIP.magnitude) < 0.02)
    err = float(np.max(np.abs(mine - a["v_f"])[~switched]))
    assert err < 0.03 * swing, (err, swing)  # measured 0.036 of 1.88 (1.9 %: the rise off the limit, a step's lag)
