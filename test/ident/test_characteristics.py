"""IEEE 115's steady-state characteristics from open- and short-circuit curves with known answers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from phid_ros.cli.main import main
from phid_ros.ident.characteristics import characterise
from phid_ros.io.field.test_sheet import SheetError, load_test_sheet
from phid_ros.sim.effects.magnetic_saturation import saturation_curve, saturation_factor

I_FG, X_DU, S10, S12 = 0.8, 1.1, 0.1, 0.4


def curves(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """An OCC on the planning models' quadratic saturation and a linear SCC, 0.2 % reading noise."""
    rng = np.random.default_rng(seed)
    a, b = saturation_curve("quadratic", S10, S12)
    v = np.array([0.25, 0.4, 0.55, 0.7, 0.85, 0.95, 1.0, 1.05, 1.1, 1.2, 1.3])
    i_f = I_FG * v * (1 + saturation_factor(False, a, b, v)) * (1 + 0.002 * rng.standard_normal(v.size))
    i_a = np.array([0.2, 0.4, 0.6, 0.8, 1.0, 1.1])
    scc_i_f = X_DU * I_FG * i_a * (1 + 0.002 * rng.standard_normal(i_a.size))
    return i_f, v, scc_i_f, i_a


def test_the_characteristics_of_known_curves_come_back() -> None:
    c = characterise(*curves())
    assert c.i_fg.value == pytest.approx(I_FG, rel=0.005)
    assert c.x_du.value == pytest.approx(X_DU, rel=0.01)
    assert c.x_d_rated.value == pytest.approx(X_DU / (1 + S10), rel=0.01)
    assert c.s10.value == pytest.approx(S10, abs=0.01) and c.s12.value == pytest.approx(S12, abs=0.02)
    assert c.planning_worst < 0.01 and c.left_out == []
    # the stds are the fits' own, of the order of the readings' 0.2 % noise over a few points
    assert 2e-4 < c.x_du.std / c.x_du.value < 0.01


def test_a_misread_linear_point_is_named_and_left_out() -> None:
    i_f, v, scc_i_f, i_a = curves(1)
    i_f[1] *= 0.92  # 0.4 pu read 8 % low
    c = characterise(i_f, v, scc_i_f, i_a)
    assert len(c.left_out) == 1 and "0.400 pu" in c.left_out[0] and "-7.7 %" in c.left_out[0]
    assert c.i_fg.value == pytest.approx(I_FG, rel=0.005)


def test_s12_beyond_the_measured_curve_is_not_extrapolated() -> None:
    i_f, v, scc_i_f, i_a = curves(2)
    keep = v <= 1.1
    c = characterise(i_f[keep], v[keep], scc_i_f, i_a)
    assert not c.s12.identifiable and any("not measured up to 1.2" in n for n in c.notes)


def _sheet(tmp_path: Path, occ_cols: str = "IF;V") -> Path:
    i_f, v, scc_i_f, i_a = curves()
    occ = [occ_cols] + [f"{a:.5f};{b * 127.0:.3f}".replace(".", ",") for a, b in zip(i_f, v)]  # decimal commas
    (tmp_path / "occ.csv").write_text("\n".join(occ) + "\n")
    scc = ["IF,IA"] + [f"{a:.5f},{b * 5.25:.4f}" for a, b in zip(scc_i_f, i_a)]
    (tmp_path / "scc.csv").write_text("\n".join(scc) + "\n")
    sheet = tmp_path / "sheet.yaml"
    sheet.write_text(
        "rated: {v: 127.0, i_a: 5.25}\nocc: {file: occ.csv, i_f: IF, v: V}\nscc: {file: scc.csv, i_f: IF, i_a: IA}\n"
    )
    return sheet


def test_phid_characterise_reads_a_sheet_and_writes_the_json(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sheet = _sheet(tmp_path)
    assert load_test_sheet(sheet).occ.x[-1] == pytest.approx(1.3, rel=1e-4)
    out = tmp_path / "c.json"
    assert main(["characterise", str(sheet), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "X_du" in text and "I_fg" in text
    import json

    doc = json.loads(out.read_text())
    assert doc["characteristics"]["x_du"]["value"] == pytest.approx(X_DU, rel=0.01)


def test_a_sheet_naming_a_missing_column_is_a_one_line_error(tmp_path: Path) -> None:
    sheet = _sheet(tmp_path, occ_cols="IF;VOLTS")
    with pytest.raises(SheetError, match=r"occ\.csv: no column 'V' \(columns: IF, VOLTS\)"):
        load_test_sheet(sheet)


def test_a_point_below_the_air_gap_line_is_named_and_left_out_not_read_as_negative_saturation() -> None:
    """An OCC point at 1.0 pu read 15 % low published S(1.0) -0.113 as identified and moved the
    short-circuit ratio by 22 %, naming no point."""
    clean = characterise(*curves(3))
    i_f, v, scc_i_f, i_a = curves(3)
    k = int(np.flatnonzero(v == 1.0)[0])
    i_f[k] *= 0.8
    c = characterise(i_f, v, scc_i_f, i_a)
    assert len(c.left_out) == 1 and "OCC point 1.000 pu" in c.left_out[0] and "below the air-gap line" in c.left_out[0]
    assert c.s10.value == pytest.approx(S10, abs=0.02) and c.s10.value > 0
    assert c.scr == pytest.approx(clean.scr, rel=0.02)


def test_a_non_finite_reading_or_json_onto_a_curve_table_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One 'nan' reading reached scipy as "ValueError: y must contain only finite values";
    ``--json`` onto the curve table the sheet names overwrote the measurements, exit 0."""
    sheet = _sheet(tmp_path)
    table = tmp_path / "occ.csv"
    measured = table.read_text()
    assert main(["characterise", str(sheet), "--json", str(table)]) == 2
    assert "occ.csv" in capsys.readouterr().err and table.read_text() == measured
    lines = measured.splitlines()
    lines[3] = lines[3].split(";")[0] + ";nan"
    table.write_text("\n".join(lines) + "\n")
    with pytest.raises(SheetError, match=r"occ\.csv: line 4, column 'V': 'nan' is not a finite number"):
        load_test_sheet(sheet)
