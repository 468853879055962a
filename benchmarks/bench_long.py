"""Long recordings: peak memory and throughput of each command against the recording's length.

    python benchmarks/bench_long.py [--hours 0.5 2] [--out benchmarks/out/long]

For each length, an ambient recording (``phid simulate --ambient``: load and voltage noise with
small steps, 1 kHz) is made once, then ``phid replay``, ``phid identify`` and ``phid info`` run on
it, each in its own process under ``/usr/bin/time`` (peak resident memory, wall time). The
limit a replay can reach is printed beside it: the time to walk and decompress the same bag
alone. Prints one row per command and length; memory that grows with the hours is what issue 39
is about (its goal: at most 1.2 GB for 2 h and for 24 h). The 24 h case (``--hours 24``) needs
about an hour and ~45 GB before that work: not for the default run.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PHID = [sys.executable, "-m", "phid_ros.cli.main"]
WALK = [
    sys.executable,
    "-c",
    "import sys; from phid_ros.io.bags import read_recording; read_recording(sys.argv[1])",
]


def measured(cmd: list[str]) -> tuple[float, float, int]:
    """(wall s, peak RSS MB, exit status) of ``cmd`` in its own process."""
    out = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M", *cmd], capture_output=True, text=True, cwd=ROOT)
    found = re.findall(r"TIME ([\d.]+) (\d+)", out.stderr)
    if not found:
        raise RuntimeError(f"{cmd}: no timing ({out.stderr[-300:]})")
    wall, kb = found[-1]
    return float(wall), int(kb) / 1024, out.returncode


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, nargs="+", default=[0.5, 2.0])
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "out" / "long")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    print(f"{'recording':>10} {'command':<10} {'wall s':>8} {'peak MB':>9} {'x real time':>12} {'exit':>5}")
    for hours in args.hours:
        seconds = int(hours * 3600)
        bag = args.out / f"ambient_{seconds}s.mcap"
        rows = []
        if not bag.exists():
            rows.append(("simulate", *measured([*PHID, "simulate", "--ambient", str(seconds), "--out", str(bag)])))
        rows.append(("read", *measured([*WALK, str(bag)])))
        replay_out = args.out / f"replay_{seconds}s.mcap"
        rows.append(("replay", *measured([*PHID, "replay", str(bag), "--out", str(replay_out), "--force"])))
        rows.append(("identify", *measured([*PHID, "identify", str(bag)])))
        rows.append(("info", *measured([*PHID, "info", str(bag)])))
        for name, wall, mb, code in rows:
            print(f"{hours:>9g}h {name:<10} {wall:>8.1f} {mb:>9.0f} {seconds / wall:>12.0f} {code:>5}")


if __name__ == "__main__":
    main()
