"""`phid diagnose` on the shipped bag with hidden saturation: the README's run, and bad input."""

from __future__ import annotations

import json
import re

import pytest

from phid_ros.cli.main import main
from test.browser import assert_readable, chromium
from test.cli.test_identify import BAGS, run_phid


# The README's run, in the default suite (about 20 s on two cores, and once more with one worker): it is
# the one end-to-end diagnosis CI checks (the random-magnitude studies are in test/diagnose/test_workflow.py).
def test_diagnose_names_the_hidden_saturation_in_the_shipped_bag(tmp_path, capsys):
    out, report = tmp_path / "diag.json", tmp_path / "diag.html"
    bag = BAGS / "saturation"
    args = ["diagnose", str(bag), "--json", str(out), "--report", str(report)]
    assert main(args + ["--truth", str(BAGS / "saturation.truth.json")]) == 0
    doc = json.loads(out.read_text())
    # the README's contract
    assert [e["name"] for e in doc["effects"]] == ["magnetic_saturation"]
    effect = doc["effects"][0]
    assert set(effect) >= {"name", "parameters", "rmse_before", "rmse_after"}
    assert effect["parameters"]["s10"] == pytest.approx(0.07, rel=0.05)
    assert effect["parameters"]["s12"] == pytest.approx(0.45, rel=0.05)
    assert doc["rmse_after"] < 0.05 * doc["rmse_before"]  # README: 21.6 -> 0.31
    assert abs(doc["errors_pct"]["after"]["T_d0_prime"]) < 1.0 < abs(doc["errors_pct"]["identified"]["T_d0_prime"])
    assert set(doc["gap_before"]["by_channel"]) == {"omega", "delta", "i_d", "i_q", "p_e", "q_e"}
    # the identification's T'_d0 and T'_q0 sat on their search bounds: shown as bounds, never as values
    assert sorted(doc["parameters_identified_at_bound"]) == ["T_d0_prime", "T_q0_prime"]
    page = report.read_text()
    assert page.count("data:image/png;base64,") == 2 and "magnetic_saturation" in page
    assert page.count("(at its search bound)") == 2
    captured = capsys.readouterr()
    out = captured.out
    assert "missing physics: magnetic_saturation" in out
    # the first fit's complaints are what the named effect explains: said so under the result, not
    # as warnings after it (six of them read as the diagnosis having failed)
    assert "the first identification (column 'identified') showed the missing physics as:" in out
    assert "  - stage 3: T_d0_prime = 15 s is at its search bound" in out
    assert re.search(r"T'_d0 +15 at bound", out), out
    assert "search bound" not in captured.err
    assert "…" not in out and max(len(line) for line in out.splitlines() if line.startswith(" ")) <= 80
    if chromium() is not None:  # rendered as a reader sees it (the other reports: test_reports_and_terminal.py)
        assert_readable(report, figures=2)
    # the candidates on one thread or on every core: the same digits (one BLAS thread either way)
    alone = tmp_path / "alone.json"
    assert (
        main(
            [
                "diagnose",
                str(bag),
                "--json",
                str(alone),
                "--workers",
                "1",
                "--truth",
                str(BAGS / "saturation.truth.json"),
            ]
        )
        == 0
    )
    doc.pop("seconds")
    assert {k: v for k, v in json.loads(alone.read_text()).items() if k != "seconds"} == doc


def test_diagnose_without_identification_scenarios_is_a_one_line_error():
    r = run_phid("diagnose", str(BAGS / "validation.mcap"))
    assert r.returncode == 2
    assert r.stderr.strip().startswith("phid: error: ") and "no identification scenarios" in r.stderr
    assert "Traceback" not in r.stderr


def test_diagnose_with_a_negative_worker_count_is_a_one_line_error():
    r = run_phid("diagnose", str(BAGS / "saturation"), "--workers", "-1")
    assert r.returncode == 2
    assert r.stderr.strip() == "phid: error: --workers -1: give 0 (every core) or a positive number of processes"


def test_parameters_the_diagnosis_did_not_determine_are_marked_in_the_table():
    from rich.console import Console

    from phid_ros.cli.diagnose import print_parameters
    from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1

    p = TABLE1.as_dict()
    doc = {"parameters_identified": p, "parameters_base_refit": p, "parameters": {**p, "X_q_prime": 0.9}}
    doc["identifiable"] = {n: n != "X_q_prime" for n in PARAMETER_NAMES}
    console = Console(width=80, record=True)
    print_parameters(console, doc)
    lines = console.export_text().splitlines()
    assert [ln for ln in lines if "n.d." in ln and "X'_q" in ln] and not [
        ln for ln in lines if "X'_d" in ln and "n.d." in ln
    ]
    assert any(ln.startswith("n.d. = not determined") for ln in lines)
