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


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_row_printed_during_the_live_line_stands_on_its_own_line(monkeypatch):
    """phid track's rows on a terminal: printed past the live line they were glued to the
    spinner's text and erased at its next redraw; printed above it they stay, each on its line.
    Where stdout is no terminal (a pipe) they go to stdout as before."""
    import sys

    from rich.console import Console

    screen = _Terminal()
    monkeypatch.setattr(sys, "__stdout__", _Terminal())
    results = io.StringIO()
    console = Console(file=results, markup=False)
    with ProgressLine("tracking", stream=screen, quiet_s=0) as p:
        time.sleep(0.3)
        p.print_above(console, "    300   3.473(11)", highlight=False)
        time.sleep(0.3)
    shown = screen.getvalue()
    # the live line cleared first (the row not after the spinner's text), the row ended by its newline
    assert "\x1b[2K    300   3.473(11)\n" in shown
    assert results.getvalue() == ""
    monkeypatch.setattr(sys, "__stdout__", io.StringIO())  # stdout a pipe: the row is a result
    with ProgressLine("tracking", stream=_Terminal(), quiet_s=0) as p:
        p.print_above(console, "    360   3.48(28)", highlight=False)
    assert results.getvalue() == "    360   3.48(28)\n"


def test_a_long_step_on_an_80_column_terminal_keeps_the_spinner_and_the_elapsed_time(monkeypatch):
    """diagnose's steps name five candidates: rich cropped the row from its right, so the elapsed time
    and the spinner vanished and the line read as hung for minutes. Now the step is cut instead."""
    monkeypatch.setenv("COLUMNS", "80")
    screen = _Terminal()
    step = "fitting 5 candidates with the base parameters: " + ", ".join(["magnetic_saturation"] * 5)
    with ProgressLine("reading", stream=screen, quiet_s=0) as p:
        p.update(step)
        time.sleep(0.3)
    frames = [re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", f) for f in screen.getvalue().split("\r")]
    drawn = [f.strip("\n") for f in frames if "fitting" in f]
    assert drawn
    for line in drawn:
        assert len(line) <= 80 and re.search(r"\d:\d\d:\d\d$", line), line
        assert line.split(" ", 1)[1].startswith("fitting 5 candidates with the base parameters: magnetic_saturation")
        assert "…" in line


def test_a_source_tells_what_another_thread_is_doing_in_a_log(monkeypatch):
    monkeypatch.setattr(progress_module, "MIN_GAP_S", 0.0)
    out = io.StringIO()
    doing = ["replaying: 480 s of stream time, 9 event(s)"]
    with ProgressLine("reading", stream=out, quiet_s=0.0, source=lambda: doing[-1]):
        time.sleep(0.5)
        doing.append("replaying: 480 s of stream time, 9 event(s); recalibrating on 9 event window(s): the exciter")
        time.sleep(0.5)
    steps = [LINE.match(line).group(1) for line in out.getvalue().splitlines()]
    assert steps[-2:] == doing


def test_replay_says_what_its_recalibration_does_once_the_file_is_read(tmp_path, capsys, monkeypatch):
    """A commissioning day's replay said "100 % of the file" from its second second and then
    "(still)" through minutes of recalibration; it says what the recalibration is doing."""
    monkeypatch.setattr(progress_module, "QUIET_S", 0.0)
    monkeypatch.setattr(progress_module, "MIN_GAP_S", 0.0)
    assert main(["replay", str(BAGS / "catalogue"), "--out", str(tmp_path / "out.mcap")]) == 0
    steps = [m.group(1) for line in capsys.readouterr().err.splitlines() if (m := LINE.match(line))]
    assert any(re.search(r"; recalibrating on \d+ event window\(s\): the (machine|exciter)", s) for s in steps), steps
    assert not any("100 % of the file" in s for s in steps)
