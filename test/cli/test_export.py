"""``phid export`` end to end: a results JSON in, a record file out, bad requests refused in one line."""

from __future__ import annotations

import json

import pytest

from phid_ros.cli.main import main
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1


def write_result(path, *, flagged: tuple[str, ...] = (), base_mva: float | None = 1000.0) -> None:
    doc = {
        "parameters": TABLE1.as_dict(),
        "identifiable": {n: n not in flagged for n in PARAMETER_NAMES},
        "f_nominal_hz": 50.0,
    }
    if base_mva is not None:
        doc["base_mva"] = base_mva
    path.write_text(json.dumps(doc))


def test_export_writes_each_format_with_the_result_base(tmp_path, capsys) -> None:
    result = tmp_path / "unit.json"
    write_result(result)
    assert main(["export", str(result), "--format", "psse-dyr", "--bus", "7", "--id", "G1"]) == 0
    dyr = (tmp_path / "unit.dyr").read_text()
    assert dyr.startswith("7 'GENROU' 'G1'") and "1000 MVA base" in dyr
    out = capsys.readouterr()
    assert "wrote" in out.out and "stated defaults (not identified)" in out.err
    assert main(["export", str(result), "--format", "pslf-dyd", "--model", "gensal"]) == 0
    assert (tmp_path / "unit.dyd").read_text().splitlines()[1].startswith('gensal 1 "BUS1" 20.00 "1" : #9 mva=1000')
    assert main(["export", str(result), "--format", "andes"]) == 0
    assert json.loads((tmp_path / "unit.andes.json").read_text())["GENROU"][0]["Sn"] == 1000.0


def test_export_refuses_flagged_parameters_and_a_missing_base(tmp_path, capsys) -> None:
    result = tmp_path / "unit.json"
    write_result(result, flagged=("X_q_prime",))
    assert main(["export", str(result), "--format", "psse-dyr"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "X_q_prime not identified; refusing" in err
    assert not (tmp_path / "unit.dyr").exists()
    assert main(["export", str(result), "--format", "psse-dyr", "--allow-flagged"]) == 0
    assert "NOT IDENTIFIED: X_q_prime" in (tmp_path / "unit.dyr").read_text()
    write_result(result, base_mva=None)
    assert main(["export", str(result), "--format", "andes"]) == 2
    assert "give it with --mva" in capsys.readouterr().err
    assert main(["export", str(result), "--format", "andes", "--mva", "250"]) == 0
    assert json.loads((tmp_path / "unit.andes.json").read_text())["GENROU"][0]["Sn"] == 250.0


def test_a_dyd_with_controls_says_which_records_it_leaves_out(tmp_path, capsys) -> None:
    from test.export.test_andes_roundtrip import CONTROLS

    result = tmp_path / "unit.json"
    write_result(result)
    result.write_text(json.dumps(json.loads(result.read_text()) | {"controls": CONTROLS}))
    assert main(["export", str(result), "--format", "pslf-dyd"]) == 0
    out = capsys.readouterr()
    assert "the SEXS record(s) are not written to a .dyd" in out.err and "TGOV1" not in out.err.split("(")[0]
    assert "wrote" in out.out and "with TGOV1" in out.out and "with SEXS" not in out.out
    assert 'tgov1 1 "BUS1" 20.00 "1" : #9 mwcap=1000 0.05 0.5' in (tmp_path / "unit.dyd").read_text()


BASE_AT_BUS_5 = (
    "5 'GENSAL' '1' 3.77 0.0552 0.0823 2.3362 0.0 1.12 0.642 0.354 0.24 0.1 0.1 0.4 /\n"
    "5 'SEXS' '1' 0.1 10.0 200.0 0.05 0.0 4.0 /\n"
    # a stabiliser reading the power of a remote bus (7), and an over-excitation limiter phid does not model
    "5 'IEEEST' '1' 3 7 0 0 0 0 0 0 0.2 0.05 0.2 0.05 3.0 3.0 -1.0 0.1 -0.1 0 0 /\n"
    "5 'MAXEX2' '1' 1.05 2.0 1.2 10.0 1.4 5.0 2.0 0.0 -0.01 /\n"
)


def test_export_onto_a_base_keeps_its_bus_its_remote_bus_and_the_records_it_does_not_model(tmp_path, capsys) -> None:
    """export --base of a unit at bus 5: written at bus 1 without --bus, the bus never said; its
    stabiliser's remote bus written as 0 (its own); its MAXEX2 dropped from the .dyr; no word of any."""
    from phid_ros.export.dyr_read import read_unit

    result, base = tmp_path / "unit.json", tmp_path / "base.dyr"
    write_result(result, base_mva=30.0)
    doc = json.loads(result.read_text())
    doc["controls"] = {
        "stabiliser": {
            "model": "IEEEST",
            "parameters": {"T1": 0.3, "T2": 0.04, "T3": 0.2, "T4": 0.05, "T6": 3.0, "KS": -0.8},
            "identifiable": dict.fromkeys(("T1", "T2", "T3", "T4", "T6", "KS"), True),
        }
    }
    result.write_text(json.dumps(doc))
    base.write_text(BASE_AT_BUS_5)
    out = tmp_path / "out.dyr"
    assert main(["export", str(result), "--format", "psse-dyr", "--base", str(base), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    written = read_unit(out)
    assert (written.bus, written.machine_id) == (5, "1")
    assert written.controls["stabiliser"].icons == {"MODE": 3, "BUSR": 7}
    assert written.controls["stabiliser"].values["KS"] == -0.8  # the identified stabiliser, at the base's bus
    assert written.controls["exciter"].model == "SEXS"  # kept: the recordings named none
    assert [r.model for r in written.carried] == ["MAXEX2"]
    assert written.carried[0].constants == (1.05, 2.0, 1.2, 10.0, 1.4, 5.0, 2.0, 0.0, -0.01)
    assert "IEEEST: BUSR = 7 kept from" in err and "MAXEX2 from" in err and "carried into the .dyr as written" in err
    # another format has no place for the limiter: said, not dropped silently
    assert (
        main(["export", str(result), "--format", "andes", "--base", str(base), "--out", str(tmp_path / "a.json")]) == 0
    )
    assert "MAXEX2 (records phid does not model) not written to a andes file" in capsys.readouterr().err


def test_a_control_record_at_a_bus_without_its_machine_or_with_limits_crossed_is_refused(tmp_path, capsys) -> None:
    """An exciter at bus 2 beside a machine at bus 1 was dropped and the unit validated on the
    recorded E_fd; an IEEEST with LSMAX below LSMIN played to an E_fd error of 9e266 pu; T5 = -3 s played."""
    from phid_ros.export.dyr_read import DyrError, read_unit

    machine = "1 'GENSAL' '1' 3.77 0.0552 0.0823 2.3362 0.0 1.12 0.642 0.354 0.24 0.1 0.1 0.4 /\n"
    cases = {
        "2 'SEXS' '1' 0.1 10.0 200.0 0.05 0.0 4.0 /\n": r"x\.dyr:2: SEXS at bus 2 id '1', where the file holds no",
        "1 'IEEEST' '1' 3 0 0 0 0 0 0 0 0.2 0.05 0.2 0.05 3.0 3.0 -1.0 -0.1 0.1 0 0 /\n": (
            r"x\.dyr:2: IEEEST LSMIN = 0\.1 lies above LSMAX = -0\.1"
        ),
        "1 'IEEEST' '1' 3 0 0 0 0 0 0 0 0.2 0.05 0.2 0.05 -3.0 3.0 -1.0 0.1 -0.1 0 0 /\n": (
            r"x\.dyr:2: IEEEST T5 = -3 is a negative time constant"
        ),
    }
    for record, message in cases.items():
        (tmp_path / "x.dyr").write_text(machine + record)
        with pytest.raises(DyrError, match=message):
            read_unit(tmp_path / "x.dyr")
