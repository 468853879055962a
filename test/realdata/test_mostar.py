"""A real hydro unit's commissioning day (../shared/realdata/mostar-dev): import, events, honesty.

The files are read where they lie and never copied here (their source states no licence); the
tests skip, saying so, where the folder is absent. Their figures are in the changelog.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

from phid_ros.api import cut_scenarios, identify_cut
from phid_ros.ident.constraints import Constraints
from phid_ros.ident.pipeline import IdentifyOptions
from phid_ros.io.bags.recordings import write_recording
from phid_ros.io.field.channel_map import ChannelMapError, load_channel_map
from phid_ros.io.field.pmu_csv import import_pmu_csv
from phid_ros.stream.levels import Level


def _realdata() -> Path:
    """Where PHID_REALDATA says, else ``shared/realdata`` beside the repository or beside one of
    its parent folders (a CI clone one level deeper than the working copy)."""
    if "PHID_REALDATA" in os.environ:
        return Path(os.environ["PHID_REALDATA"])
    repo = Path(__file__).resolve().parents[2]
    for folder in repo.parents:
        if (folder / "shared" / "realdata").is_dir():
            return folder / "shared" / "realdata"
    return repo.parent / "shared" / "realdata"


REALDATA = _realdata()
DAY = REALDATA / "mostar-dev"
pytestmark = pytest.mark.skipif(not DAY.is_dir(), reason=f"{DAY} is absent (the real recordings are not shipped)")


@pytest.fixture(scope="module")
def day(tmp_path_factory: pytest.TempPathFactory) -> Path:
    maps = [load_channel_map(DAY / "map_noload.yaml"), load_channel_map(DAY / "map_online.yaml")]
    rec = import_pmu_csv(sorted(DAY.glob("*.csv")), maps)
    out = tmp_path_factory.mktemp("mostar") / "day.mcap"
    write_recording(out, rec)
    return out


def _imported(folder: Path, online: str, noload: str) -> Path:
    """The folder's files imported with these two maps (their text), as a bag in ``folder``."""
    (folder / "map_online.yaml").write_text(online)
    (folder / "map_noload.yaml").write_text(noload)
    maps = [load_channel_map(folder / "map_noload.yaml"), load_channel_map(folder / "map_online.yaml")]
    out = folder / "day.mcap"
    write_recording(out, import_pmu_csv(sorted(DAY.glob("*.csv")), maps))
    return out


EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "mostar"  # the guide's recipe's files


@pytest.fixture(scope="module")
def sheet_day(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The day imported with the maps the guide's recipe ships (docs/examples/mostar): the
    folder's own plus what the test sheet and the controller add, the regulator's and the
    stabiliser's outputs mapped, the manual test said manual (the folder's map calls RR_* manual),
    the reference steps as stepped (+5 % on line, +10 % at no load)."""
    folder = tmp_path_factory.mktemp("mostar_sheet")
    return _imported(folder, (EXAMPLE / "map_online.yaml").read_text(), (EXAMPLE / "map_noload.yaml").read_text())


def test_no_load_tests_import_as_open_circuit_beside_the_on_line_ones() -> None:
    maps = [load_channel_map(DAY / "map_noload.yaml"), load_channel_map(DAY / "map_online.yaml")]
    rec = import_pmu_csv([DAY / "AVR_PH_Step10.csv", DAY / "AVR_MR_PSS_ON.csv"], maps)
    assert [s.name for s in rec.scenarios] == ["AVR_PH_Step10", "AVR_MR_PSS_ON"]
    assert any("AVR_PH_Step10.csv: no stator quantity mapped" in w and "P = Q = I = 0" in w for w in rec.warnings)
    assert not any("AVR_MR_PSS_ON.csv: no stator" in w for w in rec.warnings)
    pt = rec.streams["pt_ct"]
    first = pt.t_ns < rec.scenarios[0].end_ns
    assert np.all(pt.channels["p_e"][first] == 0) and np.all(pt.channels["q_e"][first] == 0)
    assert rec.metadata["not_recorded"] == "i_d,i_q,omega,delta,p_m"  # the replay judges the others
    # the regulator's and the stabiliser's outputs, which the folder's maps do not name, are said left behind
    left = "recorded but named by no channel map, so not imported: SFS_Reg_Uc (every file); SFS_PSS_VSL (AVR_MR_PSS_ON)"
    assert any(w.startswith(left) for w in rec.warnings) and rec.metadata["not_imported"] == "SFS_Reg_Uc,SFS_PSS_VSL"
    assert np.median(pt.channels["p_e"][~first]) == pytest.approx(0.61, abs=0.02)  # the on-line test's own P
    # the on-line map alone refuses the no-load file, naming what is missing
    with pytest.raises(ChannelMapError, match="SFS_Meas_PRel. for p_e is not in AVR_PH_Step10.csv"):
        import_pmu_csv([DAY / "AVR_PH_Step10.csv"], maps[1])


def test_every_event_of_a_file_is_its_own_scenario(day: Path) -> None:
    cut = cut_scenarios(day)
    by_name = {s.name: s for s in cut.scenarios}
    # SOURCE.md: the no-load +10 % step at ~13.1 s and back at ~19.4 s; the on-line AVR step at
    # ~43.7 s and back at ~53.9 s; the manual field step at 138.0 s and back at 143.5 s
    for name in (
        "AVR_PH_Step10@13.3s",
        "AVR_PH_Step10@19.6s",
        "AVR_MR_PSS_ON@43.7s",
        "AVR_MR_PSS_ON@53.9s",
        "RR_MR_Step10@138.0s",
        "RR_MR_Step10@143.7s",
    ):
        assert name in by_name, sorted(by_name)
    up, down = by_name["AVR_PH_Step10@13.3s"], by_name["AVR_PH_Step10@19.6s"]
    # each event's plateaus are its own: 1.0 -> 1.1 and 1.1 -> 1.0
    assert np.mean(up["v_t"][up.pre_slice()]) == pytest.approx(1.0006, abs=0.002)
    assert np.mean(up["v_t"][up.steady_slice()]) == pytest.approx(1.1005, abs=0.002)
    assert np.mean(down["v_t"][down.steady_slice()]) == pytest.approx(1.0006, abs=0.002)
    # the VT-loss tests are a measurement lost, not a fault of the machine: left out by name
    lost = [p for p in cut.problems if "measurement lost" in p]
    assert any("AVR_RR_PH_Ispad_Q141" in p for p in lost) and any("AVR_RR_PH_Ispad_NT_F14" in p for p in lost)
    assert not any(s.kind == "fault" for s in cut.scenarios)


def test_nothing_wrong_is_published_as_identified(day: Path) -> None:
    """The controller's field bases and the saturated no-load tests: before, T'_d0 4.63 s (for the
    datasheet's 3.77 s) came out identified with a 1 % std. What is published must be right or withheld."""
    cut = cut_scenarios(day)
    opts = IdentifyOptions(baseline=False, validate=False, constraints=Constraints(fixed={"X_q": 0.62}))
    _, res = identify_cut([(cut.scenarios, cut.problems, str(day))], opts)
    datasheet = {"X_d": 1.183, "X_d_prime": 0.371, "T_d0_prime": 3.77}
    for name, value in datasheet.items():
        e = res.estimates[name]
        if e.identifiable:
            assert abs(e.value - value) <= 2 * e.std, (name, e.value, e.std)
    t_d0 = res.estimates["T_d0_prime"]
    assert not t_d0.identifiable and "saturated part" in t_d0.note
    # X_d and X'_d by the field circuit on line rest on T'_d0 and on the field current's base, which
    # the saturated no-load plateaus leave open without the machine's curve: withheld, saying so
    for name in ("X_d", "X_d_prime"):
        e = res.estimates[name]
        assert not e.identifiable and "T'_d0, which it rests on, is not identified" in e.note, name


def test_t_d0_from_the_field_circuit_with_the_datasheet_s_curve(day: Path, tmp_path: Path) -> None:
    """The field current, recorded in every file, carries T'_d0 at no load whatever the dampers and
    the regulator did (E_fd - X_ad I_fd integrated per V_t moved). Its base needs the open-circuit
    curve: every no-load plateau here is above the knee, so without one only a bound is said; with
    the datasheet's S(1.0) 0.1, S(1.2) 0.4 (held) T'_d0 is identified. The four events (the +10 %
    step, its return, two de-excitations) put it at 4.6-5.2 s, above the datasheet's 3.77 s, and
    even S = 0 (no saturation at all, which the plateaus rule out) gives at least 4.3 s. Played in
    against the de-excitations, this T'_d0 follows the recorded decay where 3.77 s does not."""
    cut = cut_scenarios(day)
    bare = IdentifyOptions(baseline=False, validate=False, constraints=Constraints(fixed={"X_q": 0.62}))
    _, res = identify_cut([(cut.scenarios, cut.problems, str(day))], bare)
    t_d0 = res.estimates["T_d0_prime"]
    assert not t_d0.identifiable and "T'_d0 is at least 4.3" in t_d0.note and "--saturation" in t_d0.note
    held = Constraints(fixed={"X_q": 0.62}, saturation=(0.1, 0.4))
    _, res = identify_cut(
        [(cut.scenarios, cut.problems, str(day))], IdentifyOptions(baseline=False, validate=False, constraints=held)
    )
    t_d0 = res.estimates["T_d0_prime"]
    assert t_d0.identifiable and 4.5 < t_d0.value < 5.0 and t_d0.std < 0.05 * t_d0.value
    assert res.determined_by["T_d0_prime"].startswith("no-load events: the field circuit")
    # on line the field circuit gives E'_q's course: X'_d against the stator, X_d from the field
    # current on the curve. X_d within 3 % of the datasheet's 1.183 (1.160); what the on-line tests
    # fix is T'_d0 X'_d (1.44 here, the datasheet's 3.77 x 0.371 = 1.40), which the no-load T'_d0
    # splits, referred to each on-line file's field resistance (2.5-4 % above the no-load files')
    x_d, x_dp = res.estimates["X_d"], res.estimates["X_d_prime"]
    assert x_d.identifiable and x_d.value == pytest.approx(1.183, rel=0.03) and x_d.std < 0.1 * x_d.value
    assert x_dp.identifiable and 0.28 < x_dp.value < 0.33 and x_dp.std < 0.1 * x_dp.value
    assert "referred to each file's field resistance" in x_dp.note
    assert x_dp.value * t_d0.value == pytest.approx(0.371 * 3.77, rel=0.05)
    assert [e["scenario"] for e in res.route_details["field_circuit_online"].events] == [
        "AVR_MR_PSS_ON@43.7s",
        "AVR_MR_PSS_ON@53.9s",
        "RR_MR_Step10@138.0s",
        "RR_MR_Step10@143.7s",
    ]
    fc = res.route_details["field_circuit"].as_dict()
    assert [e["scenario"] for e in fc["events"]] == [
        "AVR_PH_Step10@13.3s",
        "AVR_PH_Step10@19.6s",
        "AVR_PH_Stop_INV",
        "RR_PH_Stop_INV",
    ]
    assert all(4.4 < e["T_d0_prime"] < 5.4 for e in fc["events"])
    # the step file's T'_d0 is the de-excitations' and more: the field's leakage flux, which does not
    # saturate, weighs more above the knee (dI/dV 2.7 against 1.2); at dI/dV = 1 (unsaturated) about
    # 4.55 s, nearer the datasheet's 3.77 and still above it
    leak = fc["leakage"]
    assert leak["shows"] and 0.25 < leak["T_leakage"] < 0.45 and 4.3 < leak["T_d0_prime_unsaturated"] < 4.7
    assert "the field's own leakage flux, which does not saturate, shows" in t_d0.note
    # E_fd on the machine's base, c k_e: the published fit's gain between simulated and recorded E_fd is 2.89
    for e in fc["events"]:
        assert fc["field_current_base"] * e["k_e"] == pytest.approx(2.89, rel=0.05)
    # the arbiter: the published record played against the two de-excitations (no regulator in the
    # loop: the machine alone on the recorded E_fd), as published and with this T'_d0 in it
    from phid_ros.api import validate_record

    def de_excitation_q(t_d0: float) -> list[float]:
        dyr = tmp_path / f"published_{t_d0:g}.dyr"
        dyr.write_text(
            f"1 'GENSAL' 1 {t_d0:g} 0.0552 0.0823 2.3362 0.0 1.12 0.642 0.354 0.24 0.1 0.1 0.4 /\n"
            "1 'ESST5B' 1 0.0127 505.3 0.00518 0.982 2.237 -8.384 1.701 21.98 0.0263 0.00511 1 1 1 1 1 1 1 1 /\n"
        )
        checks = validate_record(dyr, day).result.scenarios
        return [
            next(c.max_error for c in sc.checks if c.channel == "v_t")
            for sc in checks
            if sc.scenario in ("AVR_PH_Stop_INV", "RR_PH_Stop_INV")
        ]

    published, ours = de_excitation_q(3.77), de_excitation_q(t_d0.value)
    assert all(o < 0.5 * p for o, p in zip(ours, published)), (ours, published)


def test_info_lists_the_events_and_what_is_left_out(day: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from phid_ros.cli.main import main

    assert main(["info", "--wide", str(day)]) == 0
    out = capsys.readouterr().out
    assert "events (as phid identify cuts the scenarios)" in out
    for name in ("AVR_PH_Step10@13.3s", "AVR_PH_Step10@19.6s", "RR_MR_Step10@138.0s"):
        assert name in out
    assert "left out: " in out and "AVR_RR_PH_Ispad_Q141" in out and "measurement lost" in out


def test_validate_puts_the_controller_s_field_on_the_machine_base_and_plays_every_event(
    day: Path, tmp_path: Path
) -> None:
    """The published GENSAL + ST5B fit (SOURCE.md), written as a .dyr: read as published (T_B2 5.1 ms),
    its saturation and dampers played, the controller's E_fd put on the machine's base on the
    no-load plateaus with the record's own open-circuit curve, file by file from the field
    current. The published fit scaled its simulated E_fd by 1/2.89 against the recorded one; the
    no-load plateaus through I_f give 2.85-2.98 (the on-line PSS-on test's 2.887; U_f alone gave
    3.06 for every file, its 14 % drift with the field's temperature in it)."""
    from phid_ros.api import validate_record

    dyr = tmp_path / "published.dyr"
    dyr.write_text(
        "1 'GENSAL' 1 3.77 0.0552 0.0823 2.3362 0.0 1.12 0.642 0.354 0.24 0.1 0.1 0.4 /\n"
        "1 'ESST5B' 1 0.0127 505.3 0.00518 0.982 2.237 -8.384 1.701 21.98 0.0263 0.00511 1 1 1 1 1 1 1 1 /\n"
    )
    v = validate_record(dyr, day)
    [base] = [n for n in v.result.notes if n.startswith("E_fd put on the machine's base from the field current")]
    assert "E_fd = 2.848-2.982 x U_f as recorded" in base and "S(1.0) = 0.1, S(1.2) = 0.4" in base
    assert not any("saturation" in n or "damper" in n for n in v.result.notes if n.startswith("not simulated"))
    names = [sc.scenario for sc in v.result.scenarios]
    assert "AVR_PH_Step10@13.3s" in names and "AVR_PH_Step10@19.6s" in names
    # at no load the machine's own V_t, simulated on open circuit from the played E_fd: the published
    # ESST5B's ceiling (V_RMAX V_T - K_C I_FD, 1.15 pu of E_fd here) cannot hold the +10 % plateau
    up, back = (
        next(sc for sc in v.result.scenarios if sc.scenario == n)
        for n in ("AVR_PH_Step10@13.3s", "AVR_PH_Step10@19.6s")
    )
    assert [c.channel for c in up.checks] == ["v_f", "v_t"]
    assert next(c for c in up.checks if c.channel == "v_t").max_error > 0.05
    assert next(c for c in back.checks if c.channel == "v_t").max_error < 0.05
    # the on-line AVR steps, labelled voltage_step in the map, are the field's (Q rose with V_t)
    on_line = [sc for sc in v.result.scenarios if sc.scenario.startswith("AVR_MR_PSS_ON@")]
    assert len(on_line) == 2 and all(sc.kind == "field_step" for sc in on_line)
    assert all(next(c for c in sc.checks if c.channel == "q_e").max_error < 0.2 for sc in on_line)
    # a de-excitation has no regulator in the loop: E_fd as recorded, the machine checked on Q
    stop = next(sc for sc in v.result.scenarios if sc.scenario == "AVR_PH_Stop_INV")
    assert any("de-excitation" in n for n in stop.notes) and [c.channel for c in stop.checks] == ["v_t"]
    assert stop.checks[0].max_error < 0.25
    # the published ST5B's limits cannot hold the recorded operating points: said, not simulated
    assert any("limits not simulated: V_R at rest" in n for sc in on_line for n in sc.notes)


LAB = REALDATA / "usn-lab-2kva"


@pytest.mark.skipif(not LAB.is_dir(), reason=f"{LAB} is absent (the real recordings are not shipped)")
def test_a_record_that_makes_the_loop_diverge_is_played_open_loop_without_a_traceback_or_warning(
    day: Path, tmp_path: Path
) -> None:
    """A record with T_R 1e-9 s, T''_d0 1e-9 s and T_C1 = T_B1 = 1e6 s together: AssertionError in
    controls/unit_validation.py before, numpy's overflow warnings, and a NaN residual taken as a
    closed loop. Each event now says where its loop did not close and plays it open."""
    import warnings

    from phid_ros.api import validate_record

    dyr = tmp_path / "hostile.dyr"
    dyr.write_text(
        "1 'GENSAL' 1 3.77 1e-9 0.0823 2.3362 0.0 1.12 0.642 0.354 0.24 0.1 0.1 0.4 /\n"
        "1 'ESST5B' 1 1e-9 505.3 0.00518 0.982 2.237 -8.384 1e6 1e6 0.0263 0.00511 1 1 1 1 1 1 1 1 /\n"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = validate_record(dyr, day)
    notes = [n for s in got.document["validation"]["scenarios"] for n in s["notes"]]
    assert not any("nan pu)" in n and "loop closed" in n for n in notes)
    assert sum("the exciter played from the recorded V_t (its loop open)" in n for n in notes) >= 2


def test_the_laboratory_machine_s_curves(tmp_path: Path) -> None:
    """The USN laboratory machine (SOURCE.md there): X_d against the authors' 1.117 pu. Their value
    is the synchronous reactance at rated voltage (the short-circuit ratio's inverse, I_f,SC/I_f,OCC:
    their own prior 1.1271 is exactly that); IEEE 115's unsaturated X_du is 1.22 on these curves
    (the air-gap line through the OCC's measured linear part, 0.47-0.78 pu, within 0.6 %)."""
    from phid_ros.api import characterise_sheet

    sheet = tmp_path / "lab.yaml"
    sheet.write_text(
        "rated: {v: 127.017, i_a: 5.25}\n"
        f"occ: {{file: {LAB / 'test_2_OCC_data.csv'}, i_f: i_f_A, v: v_avg_V}}\n"
        f"scc: {{file: {LAB / 'test_3_SCC_data.csv'}, i_f: i_f_A, i_a: i_avg_A}}\n"
    )
    _, c = characterise_sheet(sheet)
    assert c.x_d_rated.value == pytest.approx(1.117, rel=0.05)
    assert c.x_du.value == pytest.approx(1.22, abs=0.01)
    # the air-gap line passes the measured linear part within 1 %; the one misread point is named
    assert all(abs(s) < 0.01 for v, _, s in c.occ_points if 0.4 < v < 0.8)
    assert len(c.left_out) == 1 and "0.317 pu" in c.left_out[0]
    # the open-circuit curve at its measured points: the planning models' quadratic through S(1.0), S(1.2)
    assert c.planning_worst < 0.035


def test_a_manual_test_said_in_the_map_is_played_with_its_recorded_field(tmp_path: Path) -> None:
    """RR_* files are manual tests (a field-current regulator holds I_f; the map's comment says so).
    Said in the map (``regulator: manual``), the import carries it through the bag and a CSV set,
    the exciter's fit leaves it out and validate plays its recorded E_fd: the manual field step's Q
    error falls from 6.05 pu (the AVR model played in) to 0.38 pu, its return's from 0.144 to 0.054 pu."""
    from phid_ros.api import validate_record
    from phid_ros.io.csvset.csv_export import write_csv_set

    text = (
        (DAY / "map_online.yaml")
        .read_text()
        .replace("RR_MR_Step10: {kind: field_step}", "RR_MR_Step10: {kind: field_step, regulator: manual}")
    )
    (tmp_path / "map_online.yaml").write_text(text)
    maps = [load_channel_map(DAY / "map_noload.yaml"), load_channel_map(tmp_path / "map_online.yaml")]
    rec = import_pmu_csv(sorted(DAY.glob("*.csv")), maps)  # the no-load files calibrate the field's base
    assert {s.name: s.regulator for s in rec.scenarios}["RR_MR_Step10"] == "manual"
    assert {s.name: s.regulator for s in rec.scenarios}["AVR_MR_PSS_ON"] == ""
    bag = tmp_path / "rr.mcap"
    write_recording(bag, rec)
    cut = cut_scenarios(bag)
    assert {s.name: s.regulator for s in cut.scenarios}["RR_MR_Step10@138.0s"] == "manual"
    write_csv_set(tmp_path / "set", rec)
    assert {s.name: s.regulator for s in cut_scenarios(tmp_path / "set" / "manifest.json").scenarios}[
        "RR_MR_Step10@143.7s"
    ] == "manual"
    dyr = tmp_path / "published.dyr"
    dyr.write_text(
        "1 'GENSAL' 1 3.77 0.0552 0.0823 2.3362 0.0 1.12 0.642 0.354 0.24 0.1 0.1 0.4 /\n"
        "1 'ESST5B' 1 0.0127 505.3 0.00518 0.982 2.237 -8.384 1.701 21.98 0.0263 0.00511 1 1 1 1 1 1 1 1 /\n"
    )
    v = validate_record(dyr, bag)
    manual = next(sc for sc in v.result.scenarios if sc.scenario == "RR_MR_Step10@138.0s")
    assert any("manual test" in n for n in manual.notes)
    assert next(c for c in manual.checks if c.channel == "q_e").max_error < 0.5  # 0.378; 6.05 with the AVR
    back = next(sc for sc in v.result.scenarios if sc.scenario == "RR_MR_Step10@143.7s")
    assert next(c for c in back.checks if c.channel == "q_e").max_error < 0.1  # 0.054; 0.144 with the AVR


def test_replay_counts_the_windows_of_a_trend_log_right(
    day: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """At 208 reports/s every window was refused "window has 1303 of 1304 samples": the expected
    count rounded the span over the period. Now none is refused for its sample count (the windows
    are still refused for channels this recorder never had: the monitor-on-real-channels issue)."""
    from phid_ros.cli.main import main

    assert main(["replay", str(day), "--out", str(tmp_path / "out.mcap"), "--wide"]) == 0
    out = capsys.readouterr().out
    assert "events found" in out and "samples (ring buffer too short or gap)" not in out
    # each step's size in the test sheet's terms (SOURCE.md: AVR +5 % on line, +10 % at no load, the
    # manual step +1.4 %), where the first 0.2 s said +0.010, +0.051 and +0.008 pu
    sizes: dict[str, list[str]] = {}
    for test, size in re.findall(r"^ +[0-9.]+ +field_step +(\w+) +(ΔV_t [-+][0-9.]+ pu, ΔQ [-+][0-9.]+)", out, re.M):
        sizes.setdefault(test, []).append(size)
    assert sizes["AVR_MR_PSS_ON"] == ["ΔV_t +0.049 pu, ΔQ +0.418", "ΔV_t -0.049 pu, ΔQ -0.421"], sizes  # step, return
    assert sizes["AVR_PH_Step10"] == ["ΔV_t +0.100 pu, ΔQ +0.000", "ΔV_t -0.100 pu, ΔQ +0.000"], sizes  # open circuit
    assert sizes["RR_MR_Step10"] == ["ΔV_t +0.014 pu, ΔQ +0.118", "ΔV_t -0.014 pu, ΔQ -0.119"], sizes


def test_every_output_form_of_the_import_is_read_back(day: Path, tmp_path: Path) -> None:
    """The day written as a CSV set (``--out DIR/manifest.json``) reads back in identify (the same
    numbers as the .mcap's), validate, info and replay (which refused a CSV set before)."""
    from phid_ros.cli.main import main
    from phid_ros.io.csvset.csv_export import write_csv_set

    maps = [load_channel_map(DAY / "map_noload.yaml"), load_channel_map(DAY / "map_online.yaml")]
    manifest = write_csv_set(tmp_path / "set", import_pmu_csv(sorted(DAY.glob("*.csv")), maps))
    opts = IdentifyOptions(baseline=False, validate=False, constraints=Constraints(fixed={"X_q": 0.62}))
    results = []
    for path in (day, manifest):
        cut = cut_scenarios(path)
        results.append(identify_cut([(cut.scenarios, cut.problems, str(path))], opts)[1])
    for name in ("X_d", "X_d_prime", "T_d0_prime"):
        a, b = results[0].estimates[name], results[1].estimates[name]
        assert a.identifiable == b.identifiable and a.value == pytest.approx(b.value, rel=1e-3), name
    assert main(["info", str(manifest)]) == 0
    assert main(["replay", str(manifest), "--out", str(tmp_path / "replay.mcap")]) == 0


def test_the_controller_s_own_channels_give_the_stabiliser_and_an_exciter_on_the_machine_s_base(
    tmp_path: Path,
) -> None:
    """The controller's regulator output and stabiliser output mapped (``v_r``, ``v_s``; the
    stabiliser's only in the PSS-on test, the others imported without it, said), the manual test
    said: IEEEST is named from the PSS-on test's two events (its output fitted to 0.00042 pu rms
    against 0.0018 without it), the exciter on the machine's base (the field multiplied by 2.66
    from the no-load plateaus) with its ceiling reached; a stabiliser constant given as determined
    agrees with the other event's alone (today every constant is flagged: the two events do not
    pin the stabiliser's lags, nor the exciter's constants)."""
    from phid_ros.controls.fit import ControlFit
    from phid_ros.controls.identify import identify_controls
    from phid_ros.ident.field_base import on_machine_field_base

    online = (
        (DAY / "map_online.yaml")
        .read_text()
        .replace("RR_MR_Step10: {kind: field_step}", "RR_MR_Step10: {kind: field_step, regulator: manual}")
        .replace(
            "  v_f: {name: SFS_Meas_UfRel, unit: pu}\n",
            "  v_f: {name: SFS_Meas_UfRel, unit: pu}\n  v_r: SFS_Reg_Uc\n  v_s: SFS_PSS_VSL\n",
        )
    )
    noload = (
        (DAY / "map_noload.yaml")
        .read_text()
        .replace(
            "  v_f: {name: SFS_Meas_UfRel, unit: pu}\n", "  v_f: {name: SFS_Meas_UfRel, unit: pu}\n  v_r: SFS_Reg_Uc\n"
        )
    )
    (tmp_path / "map_online.yaml").write_text(online)
    (tmp_path / "map_noload.yaml").write_text(noload)
    maps = [load_channel_map(tmp_path / "map_noload.yaml"), load_channel_map(tmp_path / "map_online.yaml")]
    rec = import_pmu_csv(sorted(DAY.glob("*.csv")), maps)
    assert any("RR_MR_Step10.csv: no v_s (SFS_PSS_VSL) in this file" in w for w in rec.warnings)
    assert sum("no stator quantity mapped" in w for w in rec.warnings) == 5  # the five no-load files only
    bag = tmp_path / "day.mcap"
    write_recording(bag, rec)
    scenarios = cut_scenarios(bag).scenarios
    assert {s.name for s in scenarios if s.has("v_s")} == {"AVR_MR_PSS_ON@43.7s", "AVR_MR_PSS_ON@53.9s"}
    on_base, note = on_machine_field_base(scenarios)
    # from the field current, file by file (each test's field resistance), on the air-gap line
    # through the least saturated plateau (no curve given)
    assert note is not None and "from the field current" in note and "E_fd = 2.604-2.726 x U_f" in note
    found = identify_controls(on_base, {"governor": []})
    pss, exciter = found["stabiliser"], found["exciter"]
    assert isinstance(pss, ControlFit) and pss.named and pss.model == "IEEEST"
    assert pss.none_heldout_rmse is not None and pss.fit_rmse < 0.3 * pss.none_heldout_rmse
    assert isinstance(exciter, ControlFit) and exciter.named and exciter.limits
    # a stabiliser constant given as determined agrees, within two stds, with the same constant
    # from the other event alone (where that event determines it)
    for left_out in ("AVR_MR_PSS_ON@43.7s", "AVR_MR_PSS_ON@53.9s"):
        alone = identify_controls([s for s in on_base if s.name != left_out], {"governor": [], "exciter": []})
        other = alone["stabiliser"]
        assert isinstance(other, ControlFit)
        for name, ok in pss.identifiable.items():
            if ok and other.identifiable.get(name):
                a, b = pss.parameters[name], other.parameters[name]
                sa, sb = pss.uncertainty[name], other.uncertainty[name]
                assert a is not None and b is not None and sa is not None and sb is not None
                assert abs(a - b) <= 2 * (sa + sb), (name, a, sa, b, sb)


PUBLISHED_FIT = (EXAMPLE / "published.dyr").read_text()  # the published GENSAL + ESST5B fit (SOURCE.md)
# the folder's SOURCE.md datasheet as the record a plant engineer writes from it (GENSAL's order:
# T'_d0 T''_d0 T''_q0 H D X_d X_q X'_d X'' X_l S(1.0) S(1.2)); no control models
DATASHEET = "1 'GENSAL' 1 3.77 0.0552 0.0823 2.137 0.0 1.183 0.62 0.371 0.215 0.1 0.1 0.4 /\n"


@pytest.fixture(scope="module")
def identified(sheet_day: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """phid identify on the sheet's day, X_q and the datasheet's curve held: its JSON and what it said."""
    import contextlib
    import io

    from phid_ros.cli.main import main

    result = tmp_path_factory.mktemp("mostar_identified") / "unit.json"
    said = io.StringIO()
    with contextlib.redirect_stdout(said):
        code = main(
            ["identify", str(sheet_day), "--fix", "X_q=0.62", "--saturation", "0.1,0.4", "--no-baseline"]
            + ["--json", str(result)]
        )
    assert code == 0
    return result, said.getvalue()


def test_identify_plays_the_no_load_tests_with_what_it_found(identified: tuple[Path, str]) -> None:
    """Before any record exists: the no-load tests on open circuit with the identified T'_d0 on
    the held curve and the named exciter (SEXS), without dampers (the day does not determine
    them). The de-excitations within MOD-026 (V_t 0.035, 0.038 for bands of 0.097); the +10 %
    step and its return miss V_t (0.018, 0.015 for 0.010) and E_fd (0.64, 0.70 for 0.38, 0.41),
    each only within 0.13 s of the event: the subtransient part, which a record's dampers supply
    (validated on the published record's, all 18 checks of the day pass)."""
    result, said = identified
    assert "the no-load tests played with the identified machine on open circuit" in said
    doc = json.loads(result.read_text())["no_load_playback"]
    assert "SEXS" in doc["unit"] and "no dampers" in doc["unit"]
    checks = {(s["scenario"], c["channel"]): c for s in doc["scenarios"] for c in s["checks"]}
    notes = {s["scenario"]: s["notes"] for s in doc["scenarios"]}
    for de_excitation in ("AVR_PH_Stop_INV", "RR_PH_Stop_INV"):
        c = checks[(de_excitation, "v_t")]
        assert c["passed"] and c["max_error"] < 0.05
    for step in ("AVR_PH_Step10@13.3s", "AVR_PH_Step10@19.6s"):
        missed = [n for n in notes[step] if "leaves its band" in n]
        failed = [ch for ch in ("v_t", "v_f") if not checks[(step, ch)]["passed"]]
        assert len(missed) == len(failed) and all("the subtransient part" in n for n in missed), notes[step]


def _checks(dyr: Path, day: Path, out: Path, *extra: str) -> dict[tuple[str, str], tuple[float, bool]]:
    """phid validate's checks of a record on the day: (scenario, channel) -> (largest error, passed)."""
    from phid_ros.cli.main import main

    assert main(["validate", str(dyr), str(day), *extra, "--json", str(out)]) in (0, 1)  # 1: a check failed
    doc = json.loads(out.read_text())["validation"]["scenarios"]
    return {(sc["scenario"], c["channel"]): (c["max_error"], c["passed"]) for sc in doc for c in sc["checks"]}


def test_identify_export_on_the_unit_s_record_validate_beats_the_published_fit(
    sheet_day: Path, identified: tuple[Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The whole chain as a plant engineer runs it, with the sheet's facts and the datasheet's
    saturation: identify (X_q held) gives T'_d0 from the field circuit, an exciter and the
    stabiliser; export writes them into the unit's existing record (the published fit: what the
    day did not determine, H, D, the dampers, kept from it and said); validate plays it. Against
    the published fit validated the same way: half its error or less on ten checks, worse on none;
    every check within MOD-026 (measured: 18 of 18, the no-load step's V_t 0.0098 on its band's
    edge, 0.0100; the published fit fails 9); both on-line AVR steps on Q, E_fd and V_t, the
    exciter's loop closed through the machine behind the network's reactance (0.120 pu, from the
    recording); the manual field step's
    Q within 0.05 pu (played from the plateau before it: from the file's start, across the Q
    ramp 100 s earlier, it began 0.38 pu away)."""
    from phid_ros.cli.main import main

    published = tmp_path / "published.dyr"
    published.write_text(PUBLISHED_FIT)
    result, said = identified
    ours = tmp_path / "unit.dyr"
    assert "what each test gave" in said and "AVR_PH_Stop_INV" in said  # the day, test by test
    args = ["--format", "psse-dyr", "--model", "GENSAL", "--base", str(published), "--allow-flagged"]
    assert main(["export", str(result), *args, "--out", str(ours)]) == 0
    assert "kept from" in capsys.readouterr().err
    text = ours.read_text()
    assert f"kept from {published} (not determined by the recordings): H, D, Xd2" in text
    checks, passed = {}, {}
    ours_dyr = ours
    for name, dyr in (("published", published), ("ours", ours)):
        found = _checks(dyr, sheet_day, tmp_path / f"{name}.json")
        checks[name] = {k: v[0] for k, v in found.items()}
        if name == "ours":
            passed = {k: v[1] for k, v in found.items()}
    # both on-line AVR steps (the step and its return, the PSS on) with the exciter's loop closed
    # behind the network the recording shows: Q, E_fd and V_t within MOD-026 (Q 0.011 and 0.011 pu;
    # played from the recorded V_t, the loop open, the return's Q was 0.111)
    for step in ("AVR_MR_PSS_ON@43.7s", "AVR_MR_PSS_ON@53.9s"):
        assert passed[(step, "q_e")] and passed[(step, "v_f")] and passed[(step, "v_t")]
        assert checks["ours"][(step, "q_e")] < 0.03
    assert passed[("RR_MR_Step10@138.0s", "q_e")]
    edge = ("AVR_PH_Step10@13.3s", "v_t")  # 0.0098 for a band of 0.0100
    assert all(ok for k, ok in passed.items() if k != edge), passed
    assert checks["ours"][edge] < 0.0105
    ours, theirs = checks["ours"], checks["published"]
    assert ours.keys() == theirs.keys()
    # no check worse than the published fit's, most far better
    worse = {k: (v, theirs[k]) for k, v in ours.items() if v > theirs[k] + 1e-3}
    assert not worse, worse
    better = [k for k, v in ours.items() if v < 0.5 * theirs[k]]
    assert len(better) >= 10, better  # E_fd on every AVR step, V_t and Q on line, V_t on the no-load events
    # the same record played from the recorded V_t, the regulator's loop open: the return's Q fails
    opened = _checks(ours_dyr, sheet_day, tmp_path / "open.json", "--open-loop")
    assert opened[("AVR_MR_PSS_ON@53.9s", "q_e")][0] > 0.1 > 0.03 > ours[("AVR_MR_PSS_ON@53.9s", "q_e")]


@pytest.fixture(scope="module")
def effect_day(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sheet's day as a recorder without the stabiliser's output would give it: no ``v_s``
    mapped, the PSS-on test said to be one (``regulator: avr+pss``)."""
    folder = tmp_path_factory.mktemp("mostar_effect")
    online = (
        (DAY / "map_online.yaml")
        .read_text()
        .replace("RR_MR_Step10: {kind: field_step}", "RR_MR_Step10: {kind: field_step, regulator: manual}")
        .replace(
            "AVR_MR_PSS_ON: {kind: voltage_step}",
            "AVR_MR_PSS_ON: {kind: voltage_step, reference_step: 0.05, regulator: avr+pss}",
        )
    )
    noload = (DAY / "map_noload.yaml").read_text() + "scenarios:\n  AVR_PH_Step10: {reference_step: 0.1}\n"
    return _imported(folder, online, noload)


def test_without_its_output_recorded_the_stabiliser_comes_from_its_effect_and_the_day_still_passes_on_q(
    effect_day: Path, tmp_path: Path
) -> None:
    """The PSS-on test with the stabiliser's output not mapped, the sheet saying it was on: the
    exciter is fitted on the no-load AVR step alone (at no load P_e does not move, nor V_S), and
    IEEEST through it from its effect on the PSS-on test's E_fd (its constants not determined: K_S
    -1.56 where the recorded output gives -1.14). Exported and validated, the stabiliser played
    from the recorded P_e throughout: both on-line AVR steps within MOD-026 on Q (0.022, 0.018) and
    V_t; E_fd 0.27 and 0.29 for bands of 0.22, 0.23 (fail; the published record's 0.87 and 0.70);
    no check worse than the published record's but the return's P, 0.014 against 0.011 (the
    published record plays no stabiliser here)."""
    from phid_ros.cli.main import main

    published, result, ours = tmp_path / "published.dyr", tmp_path / "unit.json", tmp_path / "unit.dyr"
    published.write_text(PUBLISHED_FIT)
    fixes = ["--fix", "X_q=0.62", "--saturation", "0.1,0.4", "--no-baseline"]
    assert main(["identify", str(effect_day), *fixes, "--json", str(result)]) == 0
    stabiliser = json.loads(result.read_text())["controls"]["stabiliser"]
    assert stabiliser["model"] == "IEEEST" and "from its effect on E_fd" in stabiliser["why"]
    args = ["--format", "psse-dyr", "--model", "GENSAL", "--base", str(published), "--allow-flagged"]
    assert main(["export", str(result), *args, "--out", str(ours)]) == 0
    assert "'IEEEST'" in ours.read_text()
    out = tmp_path / "ours.json"
    checks = _checks(ours, effect_day, out)
    notes = {sc["scenario"]: sc["notes"] for sc in json.loads(out.read_text())["validation"]["scenarios"]}
    theirs = _checks(published, effect_day, tmp_path / "published.json")
    for step in ("AVR_MR_PSS_ON@43.7s", "AVR_MR_PSS_ON@53.9s"):
        assert checks[(step, "q_e")][1] and checks[(step, "q_e")][0] < 0.03 and checks[(step, "v_t")][1]
        assert any("on throughout, as the test sheet says" in n for n in notes[step]), notes[step]
    # worse than the published record's only on the return's P (0.014 against 0.011 pu), which
    # plays no stabiliser here: both within a third of MOD-027's 0.05
    worse = {k: (v[0], theirs[k][0]) for k, v in checks.items() if v[0] > theirs[k][0] + 1e-3}
    assert set(worse) <= {("AVR_MR_PSS_ON@53.9s", "p_e")} and all(v < 0.017 for v, _ in worse.values()), worse


def test_on_the_datasheet_s_record_the_identified_unit_passes_every_check_of_the_day(
    sheet_day: Path, identified: tuple[Path, str], tmp_path: Path
) -> None:
    """The record a plant engineer writes from the datasheet as the unit's existing one: what the
    day determined (X_d, X'_d, T'_d0, the exciter with its ceiling, the stabiliser) replaces it,
    what the day did not (H, the dampers, X_l) is kept from it. Every check of the day passes, 18 of
    18, the no-load step and its return with room (V_t 0.006 and 0.005 against a band of 0.010; on
    the published record's X'' = 0.24 instead of the datasheet's 0.215, 0.0098 and 0.008: at no
    load the dampers' share of the field's step, (X'_d - X'')/(X'_d - X_l), is what lags V_t behind
    E_fd in the ceiling's first 50 ms). The datasheet's machine as it stands
    (T'_d0 3.77 s, X'_d 0.371), played from the recorded E_fd, fails half of its checks: the
    de-excitations' V_t by 0.17 pu, the on-line steps' Q by up to 0.075."""
    from phid_ros.cli.main import main

    datasheet, ours = tmp_path / "datasheet.dyr", tmp_path / "unit.dyr"
    datasheet.write_text(DATASHEET)
    args = ["--format", "psse-dyr", "--model", "GENSAL", "--base", str(datasheet), "--allow-flagged"]
    assert main(["export", str(identified[0]), *args, "--out", str(ours)]) == 0
    assert f"kept from {datasheet} (not determined by the recordings): H, D, Xd2, Td20, Tq20, Xl" in ours.read_text()
    checks = _checks(ours, sheet_day, tmp_path / "ours.json")
    assert len(checks) == 18 and all(ok for _, ok in checks.values()), checks
    for event in ("AVR_PH_Step10@13.3s", "AVR_PH_Step10@19.6s"):
        assert checks[(event, "v_t")][0] < 0.0075
    as_it_stands = _checks(datasheet, sheet_day, tmp_path / "datasheet.json")
    failed = [k for k, (_, ok) in as_it_stands.items() if not ok]
    assert len(failed) >= 6 and ("AVR_PH_Stop_INV", "v_t") in failed and ("RR_PH_Stop_INV", "v_t") in failed


def test_the_monitor_recalibrates_the_day_as_identify_does(sheet_day: Path) -> None:
    """Issue 53's done-when on the development day: every step and return of the AVR and manual
    tests found and its window used; the recalibration (the controller's field current carried with
    each window, a field step's window reaching back to its plateau) publishes X_d, X'_d, T'_d0 and
    the exciter equal within 1 % to identify on the same files, X_q and the curve held as the node's
    ``held`` and ``saturation`` parameters say; every declared stream's health OK (the pauses
    between the test files are the recorder's, not losses)."""
    from phid_ros.api import cut_unit, identify_unit, load_recording
    from phid_ros.controls.fit import ControlFit
    from phid_ros.io.recording import not_recorded
    from phid_ros.stream.params import held_constraints
    from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings
    from phid_ros.stream.replay import replay

    held = held_constraints("X_q=0.62", "0.1,0.4")
    rec = load_recording(sheet_day)
    settings = PipelineSettings(
        period_ns=rec.streams["pt_ct"].period_ns,
        not_recorded=not_recorded(rec.metadata),
        identify=IdentifyOptions(baseline=False, constraints=held),
    )
    pipeline = MonitorPipeline(settings)
    try:
        out = replay(rec, pipeline)
        health = {n: pipeline.status(n)[0] for n in pipeline.health}
    finally:
        pipeline.close()
    used = sorted((w.event.name for w in out.windows if w.usable), key=str)
    for test in ("AVR_MR_PSS_ON", "AVR_PH_Step10", "RR_MR_Step10"):  # each step and its return
        assert used.count(test) == 2, used
    assert used.count("AVR_PH_Stop_INV") == used.count("RR_PH_Stop_INV") == 1  # the de-excitations
    assert health == dict.fromkeys(("pt_ct", "encoder", "pmu", "excitation", "field_controller"), Level.OK), health
    last = out.recalibrations[-1]
    assert set(last.determined) == {"X_d", "X_d_prime", "T_d0_prime"} and last.parameters is None
    found = identify_unit(cut_unit([sheet_day]), IdentifyOptions(baseline=False, validate=False, constraints=held))
    for name, e in last.determined.items():
        assert e.value == pytest.approx(found.result.estimates[name].value, rel=0.01), name
    ours, theirs = last.controls["exciter"], found.controls["exciter"]
    assert isinstance(ours, ControlFit) and isinstance(theirs, ControlFit)
    # the same model named (SEXS, EXST1 and ESST5B answer the day within 5 %: the simplest), its
    # reached floor determined in both; its constant ceiling pressed on the no-load step's top (a
    # static exciter's moves with V_T and I_FD), said, ESST5B's inside
    assert ours.named and ours.model == theirs.model == "SEXS" and theirs.limits
    assert ours.pressed == theirs.pressed == ["EMAX"] and "EMAX pressed on an end of its range" in theirs.why
    determined = {n for n, ok in theirs.identifiable.items() if ok}
    assert determined == {n for n, ok in ours.identifiable.items() if ok} and determined & set(theirs.limits)
    for n in determined:
        assert ours.parameters[n] == pytest.approx(theirs.parameters[n], rel=0.01), n


def test_the_monitor_checks_the_record_on_file_at_every_event_of_the_day(
    sheet_day: Path, identified: tuple[Path, str], tmp_path: Path
) -> None:
    """The day replayed through the monitor with the unit's record on file (issue 74): the
    published GENSAL + ESST5B fit is raised (E_fd off by more than twice its band on the no-load
    step, ERROR) and T'_d0 and X'_d are said to drift from it; phid's own record (exported onto
    the published one) stays OK with every event passing. The field's base comes from the no-load
    tests as they are seen: the on-line AVR step, first in the day, is played again once they give
    it. At every event the monitor's verdict is ``phid validate``'s to the last digit: the
    online detector cuts a field step's window by the test file's rule (``window_start``: the
    sample halfway from the event before, its plateau, at most 60 s), and a file's one event is
    taken at the sample the detector finds it (a de-excitation's field step, not V_t's fall a
    second later). Before, the second event of each file began one sample later (the midpoint
    in nanoseconds) and the manual step's plateau ran 99 s: Q 0.013 against 0.030 on phid's
    record, and V_t on the published record's second no-load step passed in the monitor (0.0089)
    and failed in validate (0.0103)."""
    from phid_ros.api import record_check, validate_record
    from phid_ros.cli.main import main
    from phid_ros.io.bags.recordings import read_recording
    from phid_ros.io.recording import not_recorded
    from phid_ros.stream.params import held_constraints
    from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings
    from phid_ros.stream.replay import replay

    published, ours = tmp_path / "published.dyr", tmp_path / "unit.dyr"
    published.write_text(PUBLISHED_FIT)
    args = ["--format", "psse-dyr", "--model", "GENSAL", "--base", str(published), "--allow-flagged"]
    assert main(["export", str(identified[0]), *args, "--out", str(ours)]) == 0
    rec = read_recording(sheet_day)
    settings = PipelineSettings(
        period_ns=rec.streams["pt_ct"].period_ns,
        not_recorded=not_recorded(rec.metadata),
        identify=IdentifyOptions(baseline=False, constraints=held_constraints("X_q=0.62", "0.1,0.4")),
    )
    states = {}
    for name, dyr in (("published", published), ("ours", ours)):
        pipeline = MonitorPipeline(settings)
        pipeline.record_check = check = record_check(dyr)
        out = replay(rec, pipeline)
        pipeline.close()
        states[name] = check.status()
        final = check.verdicts
        assert len(final) == 8 and any("played again: the field's base changed" in n for n in final[0].notes)
        batch = {s.scenario: s for s in validate_record(dyr, sheet_day).result.scenarios}
        assert len(batch) == 8  # the day's events in time order, as the monitor met them
        for v, expect in zip(final, batch.values(), strict=True):
            assert [(c.channel, c.max_error, c.band, c.passed) for c in v.checks] == [
                (c.channel, c.max_error, c.band, c.passed) for c in expect.checks
            ], (name, expect.scenario)
        if name == "ours":
            assert all(v.passed for v in final) and out.verdicts
    level, message = states["published"]
    # the record's T'_d0 3.77 seen through its d damper, as fourth order: 3.846
    assert level == Level.ERROR and "E_fd off by" in message and "T'_d0: record 3.846, identified 4.78" in message
    assert states["ours"][0] == Level.OK
