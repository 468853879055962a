"""identify's ``controls`` as planning records: what goes in, what is a stated default, what is refused."""

from __future__ import annotations

import copy

import pytest

from phid_ros.export.controls import ControlExportError, build_control_records
from phid_ros.export.formats import pslf_dyd, pslf_left_out, psse_dyr
from phid_ros.export.record import build_record
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1
from test.export.test_andes_roundtrip import CONTROLS
from test.export.test_formats import read_dyd, read_dyr


def result(controls: dict) -> dict:
    return {
        "parameters": TABLE1.as_dict(),
        "identifiable": {n: True for n in PARAMETER_NAMES},
        "controls": controls,
    }


def test_named_controls_follow_the_machine_in_the_dyr_with_pss_e_s_constant_order() -> None:
    rec = build_record(result(CONTROLS), source="r.json", mva=1000.0, bus=7, machine_id="G1")
    records = read_dyr(psse_dyr(rec))
    assert [r[1] for r in records] == ["GENROU", "SEXS", "TGOV1"] and {r[0] for r in records} == {7}
    assert records[1][3] == [0.2, 5.0, 100.0, 0.05, -5.0, 5.0]  # TA/TB TB K TE EMIN EMAX
    assert records[2][3] == [0.05, 0.5, 1.0, 0.0, 2.0, 6.0, 0.0]  # R T1 VMAX VMIN T2 T3 Dt
    assert "defaults (not reached in the recordings): EMIN, EMAX" in records[1][4]


def test_nothing_named_nothing_written_and_bad_controls_are_one_line_errors() -> None:
    none = {"exciter": {"model": None, "why": "not shown"}, "governor": {"model": None, "why": "not shown"}}
    assert build_control_records(result(none), "r.json") == []
    unknown = copy.deepcopy(CONTROLS)
    unknown["exciter"]["model"] = "ESST4B"
    with pytest.raises(ControlExportError, match=r"r\.json: controls\.exciter: model 'ESST4B' is not one phid knows"):
        build_control_records(result(unknown), "r.json")
    out_of_range = copy.deepcopy(CONTROLS)
    out_of_range["governor"]["parameters"]["R"] = 5.0
    with pytest.raises(ControlExportError, match=r"controls\.governor\.R=5 pu outside \[0\.01, 0\.5\] \(the fit's"):
        build_control_records(result(out_of_range), "r.json")
    out_of_range["governor"]["parameters"]["R"] = "high"
    with pytest.raises(ControlExportError, match=r"controls\.governor\.R = 'high': not a number"):
        build_control_records(result(out_of_range), "r.json")
    # a fitted constant the data did not determine is refused, as a machine parameter is
    loose = copy.deepcopy(CONTROLS)
    loose["governor"]["identifiable"]["T3"] = False
    with pytest.raises(ControlExportError, match=r"TGOV1 T3 not identified; refusing"):
        build_control_records(result(loose), "r.json")
    [_, gov] = build_control_records(result(loose), "r.json", allow_flagged=True)
    assert gov.flagged == ["T3"] and "NOT IDENTIFIED: T3" in gov.comment()


def test_a_pslf_dyd_carries_the_governors_whose_layout_pslf_files_show_and_says_which_it_leaves_out() -> None:
    """TGOV1 and IEEEG1 follow the machine by position after mwcap= (the machine's MVA, so the per
    unit keeps its base), in PSS/E's order; IEEEG1 with PSLF's fifteen trailing values (deadbands,
    valve table) at zero. SEXS is left out of the .dyd and named as left out."""
    rec = build_record(result(CONTROLS), source="r.json", mva=1000.0, bus=7, machine_id="G1")
    records = read_dyd(pslf_dyd(rec))
    assert [r[0] for r in records] == ["genrou", "tgov1"] and records[1][1:6] == (7, "BUS7", 20.0, "G1", 1000.0)
    assert list(records[1][6].values()) == [0.05, 0.5, 1.0, 0.0, 2.0, 6.0, 0.0]  # R T1 VMAX VMIN T2 T3 Dt
    assert pslf_left_out(rec) == ["SEXS"]

    steam = copy.deepcopy(CONTROLS)
    names = ("K", "T1", "T2", "T3", "UO", "UC", "PMAX", "PMIN", "T4", "K1", "K2", "T5", "K3", "K4", "T6")
    names += ("K5", "K6", "T7", "K7", "K8")
    values = {"K": 20.0, "T3": 0.1, "T4": 0.3, "K1": 0.3, "T5": 7.0, "K3": 0.7}
    steam["governor"] = {
        "model": "IEEEG1",
        "parameters": {n: values.get(n, 0.0) for n in names} | {"UO": None, "UC": None, "PMAX": None, "PMIN": None},
        "identifiable": {n: n in values and n != "K3" for n in names},
    }
    rec = build_record(result(steam), source="r.json", mva=1000.0, bus=7, machine_id="G1")
    [_, ieeeg1] = read_dyd(pslf_dyd(rec))
    written = list(ieeeg1[6].values())
    assert ieeeg1[0] == "ieeeg1" and len(written) == 35 and written[20:] == [0.0] * 15
    assert written[:4] == [20.0, 0.0, 0.0, 0.1] and written[8:13] == [0.3, 0.3, 0.0, 7.0, 0.7]
    assert written[4:8] == [1.0, -1.0, 1.0, 0.0]  # the valve's rate and position limits: stated defaults
