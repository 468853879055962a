"""Every command's --help ends with examples and the guide that explains them; the examples are
commands the parser takes as written, and the guide exists and shows the command."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

from phid_ros.cli.parser import EXAMPLES, build_parser

GUIDES = Path(__file__).resolve().parents[2] / "docs" / "guide"


def test_every_command_has_examples() -> None:
    assert sorted(EXAMPLES) == sorted(build_parser().commands)


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_the_examples_parse_and_the_guide_shows_the_command(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser()
    lines, guide = EXAMPLES[name]
    for line in lines:
        words = shlex.split(line)
        assert words[:2] == ["phid", name]
        args, extra = parser.parse_known_args(words[1:])
        assert extra == [] and args.command == name, line
    assert f"phid {name}" in (GUIDES / guide).read_text(encoding="utf-8")
    with pytest.raises(SystemExit):
        parser.parse_args([name, "--help"])
    text = capsys.readouterr().out
    assert text.rstrip().endswith(f"guide: docs/guide/{guide}")
    assert all(f"  {line}\n" in text for line in lines)  # one example a line, as written
