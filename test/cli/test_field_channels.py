"""A commissioning day's trend logs through the command line: import, info, identify, export."""

from __future__ import annotations

import json

import pytest

from phid_ros.cli.main import main
from phid_ros.model.parameters import TABLE1
from test.io.field_sets import FIELD_BASE_V, trend_log_set


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("commissioning")
    paths, cmap = trend_log_set(d, TABLE1)
    stated = d / "stated.yaml"
    stated.write_text(cmap.read_text().replace("{name: UF, unit: V}", f"{{name: UF, unit: V, base: {FIELD_BASE_V}}}"))
    stated.write_text(stated.read_text().replace("  i_fd: {name: IF, unit: A}\n", ""))
    return d, paths, cmap, stated


def test_import_info_identify_export(folder, capsys) -> None:
    d, paths, cmap, _ = folder
    bag = d / "all.mcap"
    assert main(["import-pmu", *map(str, paths), "--map", str(cmap), "--out", str(bag)]) == 0
    err = capsys.readouterr().err
    assert "v_f (UF): 1 pu = 123." in err and "resampled onto 208 per s" in err
    assert main(["info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "what these channels determine (not recorded: theta_t, i_d, i_q, omega, delta, p_m)" in out
    assert "needs omega" in out
    result = d / "result.json"
    assert main(["identify", str(bag), "--fix", f"X_q={TABLE1.X_q}", "--json", str(result)]) == 0
    out = capsys.readouterr().out
    assert out.index("what these channels determine") < out.index("identified parameters")
    doc = json.loads(result.read_text())
    assert doc["parameters"]["H"] is None and doc["identifiable"]["H"] is False
    assert doc["parameters"]["T_d0_prime"] == pytest.approx(TABLE1.T_d0_prime, rel=0.01)
    assert doc["determined_by"]["T_d0_prime"].startswith("no-load field steps")
    # a planning record needs all eight: refused, naming the first that is missing and the way on
    assert main(["export", str(result), "--format", "psse-dyr", "--out", str(d / "unit.dyr")]) == 2
    err = capsys.readouterr().err
    assert "parameter H was not determined from the recording's channels (null)" in err and "--fix H=" in err
    # the diagnosis plays the model in against every channel: refused, by name
    assert main(["diagnose", str(bag), "--workers", "1"]) == 2
    assert "not recorded: delta, i_d, i_q, omega, p_m; the diagnosis plays" in capsys.readouterr().err


def test_two_days_two_imports_one_identification(folder, capsys) -> None:
    d, paths, cmap, stated = folder
    day1, day2 = d / "day1.mcap", d / "day2.mcap"
    assert main(["import-pmu", str(paths[0]), "--map", str(cmap), "--out", str(day1)]) == 0
    assert main(["import-pmu", *map(str, paths[1:]), "--map", str(stated), "--out", str(day2)]) == 0
    capsys.readouterr()
    result = d / "both.json"
    assert main(["identify", str(day1), str(day2), "--fix", f"X_q={TABLE1.X_q}", "--json", str(result)]) == 0
    doc = json.loads(result.read_text())
    assert doc["input"] == f"{day1} + {day2}" and len(doc["input_sha256"]) == 64
    assert [e["name"] for e in doc["events"]][:2] == ["day1/noload", "day2/step_0"]
    assert doc["parameters"]["X_d_prime"] == pytest.approx(TABLE1.X_d_prime, rel=0.03)
