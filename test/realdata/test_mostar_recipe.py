"""The guide's Mostar recipe (docs/guide/field-recordings.md) runs as written and gives its figures.

Its lines are read from the guide and run one after another in a plain shell in a new folder,
the recordings' and the shipped examples' folders given where the guide's first two lines name
them (a clone beside ``shared/realdata``, as the guide says). The figures the guide states are
held here: every check of phid's record passes (18 of 18), the published one fails 9 of 18, the
monitor with phid's record on file ends OK. About four minutes on two cores.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from test.realdata.test_mostar import DAY, EXAMPLE

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "field-recordings.md"
pytestmark = pytest.mark.skipif(not DAY.is_dir(), reason=f"{DAY} is absent (the real recordings are not shipped)")


def recipe_lines() -> list[str]:
    """The recipe's bash block: the one that begins by naming the recordings' folder."""
    block = GUIDE.read_text().split("```bash\nMOSTAR=", 1)[1].split("```", 1)[0]
    return [line for line in ("MOSTAR=" + block).splitlines() if line.strip()]


def test_the_recipe_names_its_folders_then_imports_identifies_exports_validates_and_replays() -> None:
    lines = recipe_lines()
    assert lines[0].startswith("MOSTAR=../shared/realdata/mostar-dev") and lines[1].startswith(
        "EX=docs/examples/mostar"
    )
    assert [line.split()[1] for line in lines[2:]] == [
        "import-pmu",
        "identify",
        "export",
        "validate",
        "validate",
        "replay",
    ]


def test_the_recipe_runs_as_written_and_gives_the_guide_s_figures(tmp_path: Path) -> None:
    venv = Path(sys.prefix)
    if not (venv / "bin" / "phid").is_file():
        pytest.skip(f"{venv} has no phid script (the README's set-up installs one)")
    lines = recipe_lines()
    lines[0], lines[1] = f"MOSTAR={DAY}", f"EX={EXAMPLE}"  # where this clone finds them
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    env["PATH"] = f"{venv / 'bin'}:/usr/bin:/bin"
    # each line's exit status: 0, but 1 for a validate whose record fails a check (its verdict)
    script = "".join(f'{line}\necho "exit $?" >&2\n' for line in lines)
    done = subprocess.run(["bash", "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=1800)
    codes = [int(line.split()[1]) for line in done.stderr.splitlines() if line.startswith("exit ")]
    assert codes == [0, 0, 0, 0, 0, 0, 1, 0], done.stderr[-2000:]

    def passed(name: str) -> tuple[int, int]:
        doc = json.loads((tmp_path / name).read_text())["validation"]
        checks = [c for s in doc["scenarios"] for c in s["checks"]]
        return sum(bool(c["passed"]) for c in checks), len(checks)

    assert passed("mod026.json") == (18, 18)
    assert passed("published.json") == (9, 18)
    assert "record on file: OK:" in done.stdout
    assert (tmp_path / "mod026.html").stat().st_size > 10_000 and (tmp_path / "unit.html").is_file()
