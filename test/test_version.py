"""One version: phid_ros.__version__, setup.py's metadata and both package.xml say the same."""

import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import phid_ros
from phid_ros.cli.parser import build_parser

ROOT = Path(__file__).resolve().parents[1]


def test_both_package_xml_carry_the_package_version():
    assert re.fullmatch(r"\d+\.\d+\.\d+", phid_ros.__version__)
    for xml in (ROOT / "package.xml", ROOT / "msg_schemas" / "package.xml"):
        assert ET.parse(xml).getroot().findtext("version") == phid_ros.__version__, xml


def test_setup_py_reads_the_package_version():
    out = subprocess.run(
        [sys.executable, "setup.py", "--version"], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip().splitlines()[-1] == phid_ros.__version__


def test_phid_dash_v_prints_it(capsys):
    try:
        build_parser().parse_args(["-V"])
    except SystemExit as exc:
        assert exc.code == 0
    assert capsys.readouterr().out.strip() == f"phid_ros {phid_ros.__version__}"


def test_the_changelog_names_this_version_first():
    text = (ROOT / "CHANGELOG.md").read_text()
    first = re.search(r"^## \[?(\d+\.\d+\.\d+)", text, re.M)
    assert first is not None and first.group(1) == phid_ros.__version__


def test_the_readme_states_this_version():
    """The README's front page said 0.4.0 after the release of 0.4.1: it is held here too."""
    found = re.search(r"^Version (\d+\.\d+\.\d+) ", (ROOT / "README.md").read_text(), re.M)
    assert found is not None and found.group(1) == phid_ros.__version__
