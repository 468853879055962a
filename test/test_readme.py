"""The README's tour runs as written: its lines, literally, in a plain shell, each exiting 0.

A newcomer's first line failed (``phid: command not found``: the install puts phid in .venv and
nothing said so). The tour's lines are read from the README and run one after another in a new
folder beside a ``.venv`` that is this interpreter's environment, as in a fresh clone after the
README's set-up command. About a minute with the compiled play-in ([test] brings numba).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def tour_lines() -> list[str]:
    text = (ROOT / "README.md").read_text()
    block = text.split("## A tour in six commands", 1)[1].split("\n| command", 1)[0]
    return [line[4:] for line in block.splitlines() if line.startswith("    ") and line.strip()]


def test_the_tour_names_its_environment_first_and_six_commands():
    lines = tour_lines()
    assert lines[0].startswith(". .venv/bin/activate")
    assert [line.split()[1] for line in lines[1:]] == [
        "simulate",
        "identify",
        "replay",
        "diagnose",
        "export",
        "validate",
    ]


def test_the_readme_tour_runs_as_written(tmp_path):
    venv = Path(sys.prefix)
    if not (venv / "bin" / "activate").is_file() or not (venv / "bin" / "phid").is_file():
        # colcon test runs under the ROS stack's interpreter, where phid is not this environment's script
        pytest.skip(f"{venv} is not a virtual environment with phid installed (the README's set-up makes one)")
    (tmp_path / ".venv").symlink_to(venv)
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    env["PATH"] = "/usr/bin:/bin"  # a plain shell: phid only where the tour's first line puts it
    script = "set -e\n" + "\n".join(tour_lines()) + "\n"
    done = subprocess.run(["bash", "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    for made in ("my_catalogue", "unit.json", "unit.html", "replay.mcap", "replay.html", "diag.json", "unit.dyr"):
        assert (tmp_path / made).exists(), made
    assert (tmp_path / "mod026.html").stat().st_size > 10_000


def test_the_command_table_and_each_commands_help_name_the_same_guide():
    from phid_ros.cli.parser import EXAMPLES

    rows = [line for line in (ROOT / "README.md").read_text().splitlines() if line.startswith("| `phid ")]
    for name, (_, guide) in EXAMPLES.items():
        row = next(r for r in rows if f"`phid {name}`" in r)
        assert f"docs/guide/{guide}" in row.split("|")[3], f"phid {name}: --help points to {guide}, the README to {row}"
        assert (ROOT / "docs" / "guide" / guide).exists()
