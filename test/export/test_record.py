"""The planning-model record: field sources, defaults, flags, and the orderings GENROU needs."""

from __future__ import annotations

import math

import pytest

from phid_ros.export.record import DEFAULT_TD20_S, ExportError, MachineRecord, build_record
from phid_ros.model.damper_equivalent import DamperedAxis
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1


def result(**flags: bool) -> dict:
    return {
        "parameters": TABLE1.as_dict(),
        "identifiable": {n: flags.get(n, True) for n in PARAMETER_NAMES},
        "f_nominal_hz": 50.0,
        "base_mva": 1000.0,
    }


def q_axis_plays(rec: MachineRecord) -> tuple[float, float]:
    """The fourth-order (X'_q, T'_q0) the record's q axis plays through its damper."""
    v = rec.values
    return DamperedAxis(v["Xq"], v["Xq1"], v["Xd2"], v["Xl"], v["Tq10"], v["Tq20"]).fourth_order()


def diagnosis(*effects: tuple[str, dict], **base: float) -> dict:
    return {
        "effects": [{"name": n, "parameters": p} for n, p in effects],
        "parameters": TABLE1.replace(**base).as_dict(),
    }


def test_identified_fields_and_stated_defaults() -> None:
    rec = build_record(result(), source="r.json", mva=1000.0)
    v = rec.values
    assert (v["H"], v["Xd"], v["Xd1"], v["Td10"]) == (3.48, 2.54, 0.5, 1.437)
    # without a diagnosed damper, X'' = min(X'_d, X'_q): the d-axis damper is inert, and the q
    # axis is written as the classical constants that play the identified X'_q, T'_q0 through it
    assert v["Xd2"] == 0.5 and v["Td20"] == DEFAULT_TD20_S and v["Xl"] == 0.15
    assert q_axis_plays(rec) == pytest.approx((0.814, 0.1351), rel=1e-9)
    assert v["Xq1"] == pytest.approx(1.0747, abs=1e-4) and v["Tq10"] == pytest.approx(0.1140, abs=1e-4)
    said = "identified (X_q_prime); 1.075 is the classical constant that plays 0.814 through the damper"
    assert rec.sources["Xq1"] == said
    assert any("the q axis written as X'_q = 1.075" in w for w in rec.warnings)
    assert rec.defaults == ["Td20", "Tq20", "Xd2", "Xl", "S10", "S12", "ra"]
    assert rec.sources["H"] == "identified (H)"
    assert any("stated defaults" in w and "Xl=0.15" in w for w in rec.warnings)


def test_flagged_parameters_are_refused_unless_allowed() -> None:
    with pytest.raises(ExportError, match=r"r\.json: T_q0_prime not identified; refusing"):
        build_record(result(T_q0_prime=False), source="r.json", mva=1000.0)
    rec = build_record(result(T_q0_prime=False), source="r.json", mva=1000.0, allow_flagged=True)
    assert rec.flagged == ["T_q0_prime"]
    assert "NOT IDENTIFIED: T_q0_prime" in rec.comment()
    assert rec.sources["Tq10"].endswith("NOT IDENTIFIED")


def test_diagnosed_effects_fill_subtransient_saturation_and_ra() -> None:
    sub = {"x_dpp": 0.25, "x_qpp": 0.30, "t_d0pp": 0.035, "t_q0pp": 0.06}
    diag = diagnosis(
        ("subtransient_dynamics", sub),
        ("magnetic_saturation", {"s10": 0.07, "s12": 0.45}),
        ("stator_resistance", {"r_a": 0.004}),
        H=3.5,
    )
    rec = build_record(result(), source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json")
    v = rec.values
    assert (v["Xd2"], v["Td20"], v["Tq20"], v["S10"], v["S12"], v["ra"]) == (0.25, 0.035, 0.06, 0.07, 0.45, 0.004)
    assert v["H"] == 3.5 and rec.sources["H"] == "diagnosis refit (H)"
    # the refit with the damper model found GENROU's own constants: written as they are
    assert (v["Xq1"], v["Tq10"]) == (0.814, 0.1351) and rec.sources["Xq1"] == "diagnosis refit (X_q_prime)"
    assert v["Xl"] == pytest.approx(0.15)
    assert rec.defaults == ["Xl"]
    assert any("X''_q = 0.3" in w for w in rec.warnings)  # one X'' in GENROU: the difference is said


def test_gensal_drops_the_q_axis_transient_circuit() -> None:
    rec = build_record(result(), source="r.json", mva=1000.0, model="gensal")
    assert rec.model == "GENSAL" and "Xq1" not in rec.values and "Tq10" not in rec.values
    assert rec.values["Tq20"] == 0.1351  # the fourth-order q-axis circuit is the salient machine's damper
    assert any("X'_q = 0.814 is dropped" in w for w in rec.warnings)


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        ({"effects": []}, "not an identification result"),
        ({**result(), "parameters": {**TABLE1.as_dict(), "H": math.nan}}, "parameter H is nan"),
    ],
)
def test_bad_results_are_named(doc: dict, message: str) -> None:
    with pytest.raises(ExportError, match=message):
        build_record(doc, source="r.json", mva=1000.0)


def test_an_impossible_record_is_refused() -> None:
    diag = diagnosis(("subtransient_dynamics", {"x_dpp": 0.6, "x_qpp": 0.6, "t_d0pp": 0.03, "t_q0pp": 0.05}))
    with pytest.raises(ExportError, match=r"X''=0.6 must not exceed X'_d"):
        build_record(result(), source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json")


def test_a_held_parameter_says_so() -> None:
    doc = {**result(), "constraints": {"fixed": {"D": 0.4}, "bounds": {}, "start": {}}}
    rec = build_record(doc, source="r.json", mva=1000.0)
    assert rec.sources["D"] == "held by the user (D, --fix)" and rec.sources["H"] == "identified (H)"


def test_what_the_diagnosis_did_not_determine_comes_from_the_identification_or_is_flagged() -> None:
    # the diagnosis refit put D 15 % high and could not pin X'_q (held 10 % away, the rest refit as well)
    diag = diagnosis(H=3.5, D=0.46, X_q_prime=0.95)
    diag["identifiable"] = {n: n not in ("D", "X_q_prime") for n in PARAMETER_NAMES}
    rec = build_record(result(), source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json")
    assert rec.values["H"] == 3.5 and rec.sources["H"] == "diagnosis refit (H)"
    assert rec.values["D"] == 0.4 and "the diagnosis's refit did not determine it" in rec.sources["D"]
    assert q_axis_plays(rec)[0] == pytest.approx(0.814, rel=1e-9) and not rec.flagged
    # not determined by either: refused, named, unless allowed (then marked)
    with pytest.raises(ExportError, match=r"r\.json and d\.json: X_q_prime not identified; refusing"):
        build_record(result(X_q_prime=False), source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json")
    rec = build_record(
        result(X_q_prime=False), source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json",
        allow_flagged=True,
    )  # fmt: skip
    # the refit's value, marked: it belongs with the damper and saturation values the refit named
    assert rec.flagged == ["X_q_prime"] and q_axis_plays(rec)[0] == pytest.approx(0.95, rel=1e-9)
    assert rec.sources["Xq1"].startswith("diagnosis refit (X_q_prime); ")
    assert rec.sources["Xq1"].endswith("through the damper NOT IDENTIFIED") and rec.sources["Xq1"].flagged
    # D held at stage 1's value in the diagnosis is the identification's, and says so
    diag["held"] = ["D"]
    rec = build_record(result(), source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json")
    assert rec.values["D"] == 0.4 and rec.sources["D"] == "identified (D; held at that value in the diagnosis)"
    # a parameter the identification left at a bound but the diagnosis determined is taken, identified
    diag["identifiable"]["T_q0_prime"] = True
    rec = build_record(result(T_q0_prime=False), source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json")
    assert "T_q0_prime" not in rec.flagged and rec.sources["Tq10"].startswith("diagnosis refit (T_q0_prime); ")


def test_a_field_from_an_effect_parameter_the_diagnosis_did_not_determine_is_flagged() -> None:
    # ANDES's GENROU with close q-axis time constants: T''_q0 moved 20 % between fits alike on held-out data
    sub = {"x_dpp": 0.262, "x_qpp": 0.279, "t_d0pp": 0.032, "t_q0pp": 0.035}
    diag = diagnosis(("subtransient_dynamics", sub))
    diag["effects"][0]["identifiable"] = {"x_dpp": True, "x_qpp": False, "t_d0pp": True, "t_q0pp": False}
    with pytest.raises(ExportError, match=r"r\.json and d\.json: Tq20 \(subtransient_dynamics t_q0pp\) not identified"):
        build_record(result(), source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json")
    rec = build_record(
        result(), source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json", allow_flagged=True
    )
    # x_qpp is not written (GENROU holds one X'', X''_d's), so only T''_q0 is flagged
    assert rec.flagged == ["Tq20 (subtransient_dynamics t_q0pp)"]
    assert rec.sources["Tq20"] == "diagnosis: subtransient_dynamics t_q0pp NOT IDENTIFIED"
    assert rec.sources["Xd2"] == "diagnosis: subtransient_dynamics x_dpp" and rec.values["Tq20"] == 0.035
    assert "NOT IDENTIFIED: Tq20 (subtransient_dynamics t_q0pp)" in rec.comment()


@pytest.mark.parametrize("name, value", [("H", -3.48), ("H", 3480.0), ("X_d", -2.54), ("T_d0_prime", 0.0)])
def test_an_impossible_value_is_never_written_even_when_flagged_writes_are_allowed(name: str, value: float) -> None:
    doc = result(**{name: False})
    doc["parameters"][name] = value
    with pytest.raises(ExportError, match=rf"r\.json: {name}=.* outside \[.*not a physical machine"):
        build_record(doc, source="r.json", mva=1000.0, allow_flagged=True)


def test_a_diagnosis_of_another_recording_is_refused() -> None:
    doc = result() | {"input": "unit_a.mcap", "input_sha256": "a" * 64}
    diag = diagnosis(("stator_resistance", {"r_a": 0.004})) | {"input": "unit_b.mcap", "input_sha256": "b" * 64}
    with pytest.raises(ExportError, match=r"d\.json: diagnoses unit_b\.mcap, but r\.json identified unit_a\.mcap"):
        build_record(doc, source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json")
    # the same content under another name is the same recording
    diag |= {"input": "copy_of_a.mcap", "input_sha256": "a" * 64}
    assert (
        build_record(doc, source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json").values["ra"] == 0.004
    )
    # results from before the digest: compared by path, normalised
    old_doc, old_diag = result() | {"input": "./bags/x"}, diagnosis() | {"input": "bags/x"}
    build_record(old_doc, source="r.json", mva=1000.0, diagnosis=old_diag, diagnosis_source="d.json")
    with pytest.raises(ExportError, match="another file"):
        build_record(
            old_doc, source="r.json", mva=1000.0, diagnosis=diagnosis() | {"input": "bags/y"}, diagnosis_source="d.json"
        )


@pytest.mark.parametrize("machine_id", ["1\n1 'GENCLS' 1 0 0 /", "1'", '1"', "", "ABC", "1 "])
def test_a_machine_id_that_would_break_or_inject_a_record_is_refused(machine_id: str) -> None:
    """``--id`` was written between quotes unchecked: a newline injected a second PSS/E record, a
    quote ended the record early, a '"' broke a .dyd."""
    with pytest.raises(ExportError, match=r"--id .*: a machine id is one or two letters or digits"):
        build_record(result(), source="r.json", mva=1000.0, machine_id=machine_id)
    assert build_record(result(), source="r.json", mva=1000.0, machine_id="G1").machine_id == "G1"


def test_a_result_path_with_a_newline_stays_in_the_records_comment() -> None:
    """The result's path is written into the record's comment: a newline in it began a new line
    that PSS/E and PSLF read as a record."""
    from phid_ros.export.formats import pslf_dyd, psse_dyr

    rec = build_record(result(), source="x\n1 'GENCLS' 1 0 0 /\n.json", mva=1000.0)
    dyr = psse_dyr(rec)
    assert "GENCLS" in dyr and not any(line.startswith("1 'GENCLS'") for line in dyr.splitlines())
    assert len(dyr.splitlines()) == len(psse_dyr(build_record(result(), source="r.json", mva=1000.0)).splitlines())
    assert not any(line.startswith("1 'GENCLS'") for line in pslf_dyd(rec).splitlines())


def test_the_saturation_held_in_the_identification_is_the_record_s() -> None:
    # phid identify --saturation 0.1,0.4: the datasheet's curve the field base was read on
    doc = {**result(), "constraints": {"fixed": {}, "saturation": {"S10": 0.1, "S12": 0.4}}}
    rec = build_record(doc, source="r.json", mva=1000.0)
    assert (rec.values["S10"], rec.values["S12"]) == (0.1, 0.4)
    assert rec.sources["S10"] == "held by the user (--saturation)" and "S10" not in rec.defaults
    diag = diagnosis(("magnetic_saturation", {"s10": 0.07, "s12": 0.45}))
    rec = build_record(doc, source="r.json", mva=1000.0, diagnosis=diag, diagnosis_source="d.json")
    assert (rec.values["S10"], rec.values["S12"]) == (0.1, 0.4)
    assert any("keeps the curve the identification held" in w for w in rec.warnings)


def test_what_the_recordings_did_not_determine_is_kept_from_the_unit_s_record(tmp_path) -> None:
    """phid export --base UNIT.dyr: a commissioning day that determined T'_d0 and the exciter, not
    H, X_d, X'_d (a trend log without the rotor's channels): the record is the unit's existing one
    with T'_d0 replaced; its dampers and saturation stay; its governor stays (none identified)."""
    from phid_ros.export.dyr_read import read_unit

    dyr = tmp_path / "unit.dyr"
    dyr.write_text(
        "1 'GENSAL' 1 3.77 0.0552 0.0823 2.3362 0.0 1.12 0.642 0.354 0.24 0.1 0.1 0.4 /\n"
        "1 'SEXS' 1 0.1 10.0 200.0 0.05 0.0 4.0 /\n"
        "1 'HYGOV' 1 0.05 0.3 5.0 0.05 0.2 5.0 1.0 0.0 1.0 1.2 1.0 0.0 /\n"
    )
    unit = read_unit(dyr)
    doc = result(H=False, D=False, X_d=False, X_d_prime=False, X_q_prime=False, T_q0_prime=False)
    doc["parameters"] = {**doc["parameters"], "H": None, "T_d0_prime": 4.78, "X_q": 0.62}
    doc["operating_point"] = {"p_m_pu": 0.6}
    doc["constraints"] = {"fixed": {"X_q": 0.62}}
    doc["controls"] = {
        "exciter": {
            "model": "SEXS",
            "parameters": {"TA/TB": 0.09, "TB": 24.0, "K": 600.0, "TE": 0.004, "EMIN": -3.4, "EMAX": 4.7},
            "identifiable": {"TA/TB": True, "TB": True, "K": True, "TE": True, "EMIN": True, "EMAX": True},
        },
        "governor": {"model": None, "why": "no scenario with omega and p_m"},
    }
    with pytest.raises(ExportError, match=r"H was not determined .*\(phid export --base UNIT\.dyr\)"):
        build_record(doc, source="r.json", model="GENSAL", mva=30.0)
    rec = build_record(doc, source="r.json", model="GENSAL", mva=30.0, existing=unit)
    v, src = rec.values, rec.sources
    assert (v["Td10"], v["H"], v["Xd"], v["Xd1"], v["Xq"]) == (4.78, 2.3362, 1.12, 0.354, 0.62)
    assert src["H"].startswith(f"kept from {dyr}") and src["Td10"] == "identified (T_d0_prime)"
    assert src["Xq"].startswith("held by the user")
    assert v["D"] == pytest.approx(0.6) and rec.torque_form_damping() == pytest.approx(0.0)  # PSS/E's D back
    assert (v["Xd2"], v["Td20"], v["Tq20"], v["Xl"], v["S10"], v["S12"]) == (0.24, 0.0552, 0.0823, 0.1, 0.1, 0.4)
    assert not rec.flagged and rec.kept == ["H", "D", "Xd", "Xd1", "Xd2", "Td20", "Tq20", "Xl", "S10", "S12"]
    assert f"kept from {dyr} (not determined by the recordings): H, D, Xd" in rec.comment()
    exciter, governor = rec.controls
    assert (exciter.model, exciter.values["K"]) == ("SEXS", 600.0)  # the identified one replaces the record's
    assert governor.model == "HYGOV" and governor.values == unit.controls["governor"].values
    assert governor.comment() == f"phid_ros export: governor kept from {dyr} (the recordings named none)"


def test_a_withheld_value_is_written_only_flagged() -> None:
    """A result of 2026-12 on: the value not identified is null under ``parameters`` and kept
    under ``withheld``; the record refuses it, and writes it flagged when allowed, as before."""
    doc = result(T_q0_prime=False)
    doc["withheld"] = {"T_q0_prime": {"value": doc["parameters"]["T_q0_prime"], "std": 0.1, "why": "poor"}}
    doc["parameters"] = {**doc["parameters"], "T_q0_prime": None}
    with pytest.raises(ExportError, match=r"r\.json: T_q0_prime not identified; refusing"):
        build_record(doc, source="r.json", mva=1000.0)
    rec = build_record(doc, source="r.json", mva=1000.0, allow_flagged=True)
    assert rec.flagged == ["T_q0_prime"]
    assert q_axis_plays(rec)[1] == pytest.approx(doc["withheld"]["T_q0_prime"]["value"], rel=1e-9)
