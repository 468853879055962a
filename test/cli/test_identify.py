"""phid identify end to end: JSON contract, inputs of every kind, bad inputs."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from phid_ros.cli.main import main
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1

BAGS = Path(__file__).resolve().parents[2] / "bags"


def test_identify_shipped_catalogue_writes_the_contract(tmp_path, capsys):
    out = tmp_path / "result.json"
    report = tmp_path / "report.html"
    assert (
        main(
            [
                "identify",
                str(BAGS / "catalogue"),
                "--json",
                str(out),
                "--truth",
                str(BAGS / "catalogue.truth.json"),
                "--report",
                str(report),
            ]
        )
        == 0
    )
    doc = json.loads(out.read_text())
    for key in ("parameters", "uncertainty", "method", "events", "validation"):
        assert key in doc
    assert set(doc["parameters"]) == set(PARAMETER_NAMES) == set(doc["uncertainty"])
    for name in PARAMETER_NAMES:
        limit = 5.0 if name == "D" else 1.0  # D: see the README on its noise floor
        assert abs(doc["errors_pct"][name]) < limit, (name, doc["errors_pct"][name])
    assert doc["validation"]["max_rms_delta_deg"] < 0.2
    assert doc["validation"]["max_rms_omega_pct"] < 0.02
    assert len(doc["events"]) == 18
    text = capsys.readouterr().out
    assert "IEEE 115" in text and "T'_q0" in text and "V3_fault_150ms" in text
    page = report.read_text()
    assert page.count("data:image/png;base64,") >= 4 and "<table>" in page


def test_identify_a_csv_manifest(tmp_path, catalogue_runs):
    from test.io.csvset.test_csv_import import write_set

    runs = [r for r in catalogue_runs if r.scenario.name[:3] in ("S04", "S06", "S09", "S10", "S13", "S15", "V1_")]
    # CSV exports of a plant rarely say what each file is: leave kind 'unknown' to be classified
    manifest = write_set(tmp_path, runs)
    data = json.loads(manifest.read_text())
    for entry in data["scenarios"]:
        entry["kind"] = "unknown"
    manifest.write_text(json.dumps(data))
    out = tmp_path / "r.json"
    assert main(["identify", str(manifest), "--json", str(out), "--no-baseline"]) == 0
    doc = json.loads(out.read_text())
    kinds = [e["kind"] for e in doc["events"]]
    assert kinds == ["torque_step", "torque_step", "voltage_step", "voltage_step", "fault", "fault", "torque_step"]
    assert doc["parameters"]["X_d"] == pytest.approx(TABLE1.X_d, rel=1e-3)
    assert doc["parameters"]["T_d0_prime"] == pytest.approx(TABLE1.T_d0_prime, rel=0.02)


def test_identify_a_bag_without_markers(tmp_path, short_recording):
    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.io.recording import Recording

    bare = Recording(streams=short_recording.streams, scenarios=[], metadata=short_recording.metadata)
    path = write_recording(tmp_path / "plant.mcap", bare)
    out = tmp_path / "r.json"
    assert main(["identify", str(path), "--json", str(out), "--no-baseline"]) == 0
    doc = json.loads(out.read_text())
    assert any("no scenario markers" in p for p in doc["problems"])
    kinds = [e["kind"] for e in doc["events"]]
    assert kinds[:1] == ["torque_step"] and "fault" in kinds and "voltage_step" in kinds
    assert math.isfinite(doc["parameters"]["H"])


def run_phid(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "phid_ros.cli.main", *args], capture_output=True, text=True)


def test_inconsistent_frequency_between_truth_and_bag(tmp_path):
    truth = json.loads((BAGS / "validation.mcap.truth.json").read_text())
    truth["f_nominal_hz"] = 60
    bad = tmp_path / "t.json"
    bad.write_text(json.dumps(truth))
    r = run_phid("identify", str(BAGS / "validation.mcap"), "--truth", str(bad))
    assert r.returncode == 2
    assert r.stderr.strip() == f"phid: error: {bad}: nominal frequency 60 Hz differs from the recording's 50.0 Hz"


def test_truth_file_with_a_wrong_name(tmp_path):
    """A misspelt parameter leaves one missing: refused, naming both the missing and the ignored key."""
    values = TABLE1.as_dict()
    values["Xdp"] = values.pop("X_d_prime")
    bad = tmp_path / "t.json"
    bad.write_text(json.dumps({"parameters": values}))
    r = run_phid("identify", str(BAGS / "validation.mcap"), "--truth", str(bad))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert (
        "missing parameter(s) ['X_d_prime']" in r.stderr and "ignored key(s) that are not parameters: Xdp" in r.stderr
    )


@pytest.mark.parametrize("nested", [True, False])
def test_truth_file_with_metadata_beside_the_parameters(tmp_path, capsys, nested):
    """A plant's truth file carries more than the eight: unit, date, source. Ignored, with a note."""
    from phid_ros.cli.common import load_parameters

    meta = {"unit": "G1", "date": "2026-11-01", "source": "OEM datasheet"}
    doc = {**meta, "parameters": TABLE1.as_dict()} if nested else {**meta, **TABLE1.as_dict()}
    truth = tmp_path / "t.json"
    truth.write_text(json.dumps(doc))
    assert load_parameters(truth) == TABLE1
    err = capsys.readouterr().err
    if nested:  # keys beside a nested 'parameters' object are the document's own business
        assert err == ""
    else:
        assert err.strip() == f"phid: warning: {truth}: ignored key(s) that are not parameters: date, source, unit"


def test_inconsistent_base_between_truth_and_bag(tmp_path):
    truth = json.loads((BAGS / "validation.mcap.truth.json").read_text())
    truth["base_mva"] = 500
    bad = tmp_path / "t.json"
    bad.write_text(json.dumps(truth))
    r = run_phid("identify", str(BAGS / "validation.mcap"), "--truth", str(bad))
    assert r.returncode == 2 and "base 500 MVA differs from the recording's 1000 MVA" in r.stderr


def test_a_nan_window_is_skipped_by_name_and_the_rest_identified(tmp_path, short_recording):
    import numpy as np

    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.io.recording import Recording, StreamSamples

    pmu = short_recording.streams["pmu"]
    delta = pmu.channels["delta"].copy()
    sc = short_recording.scenarios[1]
    k = int(np.searchsorted(pmu.t_ns, sc.event_ns)) + 200
    delta[k : k + 20] = np.nan  # 20 ms: longer than the aligner bridges (5 samples), as in replay
    streams = dict(short_recording.streams)
    streams["pmu"] = StreamSamples(pmu.t_ns, pmu.period_ns, {"theta_t": pmu.channels["theta_t"], "delta": delta})
    path = write_recording(
        tmp_path / "nan.mcap", Recording(streams, short_recording.scenarios, short_recording.metadata)
    )
    out = tmp_path / "r.json"
    assert main(["identify", str(path), "--json", str(out), "--no-baseline"]) == 0
    doc = json.loads(out.read_text())
    # the aligner drops a stream's sample as a whole, so both PMU channels carry the hole
    assert any(
        f"skipped scenario {sc.name}: channel theta_t has 20 NaN" in p and str(path) in p for p in doc["problems"]
    )
    assert [e["name"] for e in doc["events"]] == [short_recording.scenarios[0].name, short_recording.scenarios[2].name]


def test_a_sister_unit_s_result_is_compared_parameter_by_parameter(tmp_path, capsys) -> None:
    """Sister units of one design (issue 71): a parameter both identify further apart than two
    combined stds is said and kept in the JSON; a sister that agrees says nothing; a file that is
    not a result is refused by name before the identification."""
    import json

    from phid_ros.cli.main import main

    mine = tmp_path / "mine.json"
    assert main(["identify", "bags/catalogue", "--no-baseline", "--json", str(mine)]) == 0
    doc = json.loads(mine.read_text())
    same, apart = tmp_path / "same.json", tmp_path / "apart.json"
    same.write_text(json.dumps(doc))
    doc["parameters"]["T_d0_prime"] *= 1.3
    apart.write_text(json.dumps(doc))
    out = tmp_path / "with_sisters.json"
    capsys.readouterr()
    args = ["identify", "bags/catalogue", "--no-baseline", "--sister", str(same), "--sister", str(apart)]
    assert main([*args, "--json", str(out)]) == 0
    said = capsys.readouterr()
    sisters = json.loads(out.read_text())["sisters"]
    assert sisters["compared_with"] == [str(same), str(apart)]
    assert [(g["parameter"], g["sister"]) for g in sisters["apart"]] == [("T_d0_prime", str(apart))]
    gap = sisters["apart"][0]
    assert gap["there"] == pytest.approx(1.3 * gap["here"]) and gap["sigmas"] > 2.0
    assert "T'_d0: 1.436 ± 0.00083 here, 1.867 ± 0.00083 in the sister unit's" in said.err
    assert "+30.0% there" in said.err
    bad = tmp_path / "bad.json"
    bad.write_text('{"H": 3.5}')
    assert main(["identify", "bags/catalogue", "--sister", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.json: not an identification's results" in err and "identified parameters" not in err
