"""Make the README's report screenshots: run each command with --report on the shipped bags, then
photograph the page in headless Chromium (Debian's ``chromium``). About six minutes on two cores,
most of it the diagnosis.

    python docs/make_screenshots.py [--reports DIR]   # DIR: keep the HTML reports there (default: a temp dir)
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from phid_ros.cli.main import main  # noqa: E402
from test.browser import assert_readable, chromium, screenshot  # noqa: E402

# every path a report shows is relative (the reports are made in their folder, the shipped bags
# linked into it as ``bags``), so a screenshot never shows where the docs were built
BAGS = Path("bags")
FIGURES = {"identify": 4, "diagnose": 2, "replay": 3, "track": 3, "validate": 18, "history": 1}


def make_reports() -> None:
    """The reports, made in the current folder from the bags linked there."""
    if not BAGS.exists():
        BAGS.symlink_to(ROOT / "bags", target_is_directory=True)
    out = Path(".")
    runs = {
        "identify": ["identify", str(BAGS / "catalogue"), "--truth", str(BAGS / "catalogue.truth.json")],
        "diagnose": ["diagnose", str(BAGS / "saturation"), "--truth", str(BAGS / "saturation.truth.json")],
        "replay": ["replay", str(BAGS / "catalogue"), "--out", str(out / "replay_out.mcap"), "--force"],
    }
    for name, args in runs.items():
        if not (out / f"{name}.html").exists():
            assert main(args + ["--report", str(out / f"{name}.html")]) == 0
    if not (out / "validate.html").exists():  # the tour's last line: the identified unit's record, MOD-026/027
        ident = ["identify", str(BAGS / "catalogue"), "--json", str(out / "unit.json")]
        assert main(ident) == 0
        assert main(["export", str(out / "unit.json"), "--format", "psse-dyr", "--out", str(out / "unit.dyr")]) == 0
        validate = ["validate", str(out / "unit.dyr"), str(BAGS / "catalogue"), "--report", str(out / "validate.html")]
        assert main(validate) == 0
    if not (out / "history.html").exists():  # one unit on three days, the third with T'_d0 drifted +8 %
        unit = out / "fleet_inventory" / "U1"
        unit.mkdir(parents=True, exist_ok=True)
        for seed, day, drift in (
            (1, "2026-01-05", []),
            (2, "2026-02-05", []),
            (3, "2026-03-05", ["--drift", "T_d0_prime=0.08@0-30"]),
        ):
            bag = unit / f"{day}.mcap"
            if not bag.exists():
                simulate = ["simulate", "--ambient", "600", "--seed", str(seed), "--start", f"{day}T06:00:00Z"]
                assert main([*simulate, *drift, "--out", str(bag)]) == 0
        assert main(["fleet", str(out / "fleet_inventory"), "--out", str(out / "fleet"), "--workers", "1"]) == 0
        assert main(["history", "U1", "--fleet", str(out / "fleet"), "--report", str(out / "history.html")]) == 0
    if not (out / "track.html").exists():
        bag = out / "drift.mcap"
        if not bag.exists():
            assert (
                main(["simulate", "--ambient", "1200", "--drift", "T_d0_prime=0.15@300-1100", "--out", str(bag)]) == 0
            )
        assert main(["track", str(bag), "--report", str(out / "track.html")]) == 0


def run(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reports", type=Path, help="folder for the HTML reports (reused if already there)")
    args = parser.parse_args(argv)
    if chromium() is None:
        print("no Chromium: apt-get install chromium", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        out = args.reports or Path(tmp)
        out = out.resolve()
        out.mkdir(parents=True, exist_ok=True)
        here = Path.cwd()
        os.chdir(out)
        try:
            make_reports()
        finally:
            os.chdir(here)
        for name, figures in FIGURES.items():
            assert_readable(out / f"{name}.html", figures)
            # validate's page holds every event's figure: its top (the checks' table and the first events) suffices
            height = 4200 if name == "validate" else None
            shot = screenshot(out / f"{name}.html", ROOT / "docs" / f"{name}_report.jpg", height=height)
            print(f"{shot.relative_to(ROOT)}: {shot.stat().st_size / 1e3:.0f} kB")
    return 0


if __name__ == "__main__":
    sys.exit(run())
