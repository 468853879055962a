"""Progress lines: plain lines on stderr in a log, none for a quick command, stdout untouched."""

from __future__ import annotations

import io
import re
import time
from pathlib import Path

from phid_ros.cli import progress as progress_module
from phid_ros.cli.main import main
from phid_ros.cli.progress import ProgressLine

BAGS = Path(__file__).resolve().parents[2] / "bags"
LINE = re.compile(r"^phid \[ *\d+\.\d s\] (.+)$")


def test_plain_lines_once_per_step_after_the_quiet_time(monkeypatch):
    monkeypatch.setattr(progress_module, "MIN_GAP_S", 0.1)
    out = io.StringIO()
    with ProgressLine("step one", stream=out, quiet_s=0.3) as p:
        time.sleep(0.1)
        p.update("step two")  # step one ended within the quiet time: never printed
        time.sleep(0.8)
        p.update("step three")
        time.sleep(0.8)
    steps = [LINE.match(line).group(1) for line in out.getvalue().splitlines()]
    assert steps == ["step two", "step three"]


def test_a_quick_command_prints_no_progress():
    out = io.StringIO()
    with ProgressLine("reading", stream=out) as p:
        p.update("identifying")
    assert out.getvalue() == ""


def test_identify_reports_each_stage_on_stderr_in_a_log(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(progress_module, "QUIET_S", 0.0)
    monkeypatch.setattr(progress_module, "MIN_GAP_S", 0.0)
    assert main(["identify", str(BAGS / "catalogue"), "--json", str(tmp_path / "r.json")]) == 0
    cap = capsys.readouterr()
    steps = [m.group(1) for m in map(LINE.match, cap.err.splitlines()) if m]
    assert steps[0].startswith("reading ")
    # a step shows when it begins, however short (no quiet time, no gap here): the three stages in order
    shown = [s.split(":")[0] for s in steps if s.startswith("stage")]
    assert shown == ["stage 1", "stage 2", "stage 3"]
    assert "phid [" not in cap.out
