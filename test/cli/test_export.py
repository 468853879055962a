"""``phid export`` end to end: a results JSON in, a record file out, bad requests refused in one line."""

from __future__ import annotations

import json

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
