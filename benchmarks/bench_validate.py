"""``phid validate`` with the exciter's loop closed against the same play-in with it open.

    python benchmarks/bench_validate.py [--runs 3] [--dyr UNIT.dyr --input DAY.mcap]

Plays one record against one recording both ways, alternated run by run (a noisy machine slows
both alike), and prints each one's median wall time, the ratio of the closed loop's to the open
one's (the baseline, in the same run), how many checks fail, the largest Q error on line, and the
peak resident memory of the process.

Without ``--dyr``/``--input``: the Mostar unit's development files (``../shared/realdata/mostar-dev``,
imported with the folder's maps and the test sheet's reference steps) against the published GENSAL
+ ST5B fit of that unit (its constants from the folder's SOURCE.md); the files are not shipped,
so without them the script says so and stops.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

from phid_ros.api import validate_record

ROOT = Path(__file__).resolve().parents[1]
MOSTAR = ROOT.parent / "shared" / "realdata" / "mostar-dev"
# the published fit (SOURCE.md there: ALSETLab's RaPId fit, GENSAL + ST5B)
PUBLISHED = (
    "1 'GENSAL' 1 3.77 0.0552 0.0823 2.3362 0.0 1.12 0.642 0.354 0.24 0.1 0.1 0.4 /\n"
    "1 'ESST5B' 1 0.0127 505.3 0.00518 0.982 2.237 -8.384 1.701 21.98 0.0263 0.00511 1 1 1 1 1 1 1 1 /\n"
)


def mostar_day(folder: Path) -> tuple[Path, Path]:
    """The development day as one .mcap (the test sheet's reference steps added to the maps) and the
    published record."""
    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.io.field.channel_map import load_channel_map
    from phid_ros.io.field.pmu_csv import import_pmu_csv

    online = (MOSTAR / "map_online.yaml").read_text()
    online = online.replace(
        "AVR_MR_PSS_ON: {kind: voltage_step}", "AVR_MR_PSS_ON: {kind: voltage_step, reference_step: 0.05}"
    )
    online = online.replace("RR_MR_Step10: {kind: field_step}", "RR_MR_Step10: {kind: field_step, regulator: manual}")
    noload = (MOSTAR / "map_noload.yaml").read_text() + "scenarios:\n  AVR_PH_Step10: {reference_step: 0.1}\n"
    (folder / "map_online.yaml").write_text(online)
    (folder / "map_noload.yaml").write_text(noload)
    maps = [load_channel_map(folder / "map_noload.yaml"), load_channel_map(folder / "map_online.yaml")]
    day = folder / "day.mcap"
    write_recording(day, import_pmu_csv(sorted(MOSTAR.glob("*.csv")), maps))
    dyr = folder / "published.dyr"
    dyr.write_text(PUBLISHED)
    return dyr, day


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--dyr", type=Path)
    parser.add_argument("--input", type=Path)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.dyr and args.input:
            dyr, day = args.dyr, args.input
        elif MOSTAR.is_dir():
            dyr, day = mostar_day(Path(tmp))
        else:
            print(f"{MOSTAR} is absent (the real recordings are not shipped): give --dyr and --input")
            return 1
        times: dict[str, list[float]] = {"open loop": [], "closed loop": []}
        found = {}
        for _ in range(args.runs):
            for name in times:
                t0 = time.perf_counter()
                found[name] = validate_record(dyr, day, open_loop=name == "open loop").result
                times[name].append(time.perf_counter() - t0)
    base = statistics.median(times["open loop"])
    print(f"{dyr.name} against {day.name}, {args.runs} runs each, alternated")
    print(f"{'play-in':<12} {'median s':>9} {'ratio':>6} {'checks failed':>14} {'largest Q error pu':>19}")
    for name, ts in times.items():
        result = found[name]
        checks = [c for sc in result.scenarios for c in sc.checks]
        q = max((c.max_error for c in checks if c.channel == "q_e"), default=float("nan"))
        failed = sum(not c.passed for c in checks)
        wall = statistics.median(ts)
        print(f"{name:<12} {wall:9.2f} {wall / base:6.2f} {failed:>6} of {len(checks):<5} {q:19.3f}")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory {peak_mb:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
