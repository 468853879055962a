"""A recorder's channels identified: the cost of leaving each test file out in turn.

    python benchmarks/bench_partial_channels.py [--runs 3]

Makes the simulated commissioning day of trend logs (a no-load field step, four on-line field
steps and two grid steps at 208 reports/s: V_t, P, Q, I_t, E_fd, I_fd only; the TABLE 1
machine), imports it, and times ``phid identify`` on it (X_q held) with each of its seven test
files left out in turn and without that check (the baseline, in the same run): medians over
``--runs``, their ratio, the estimates of both (the check must not move a right one), and the
peak resident memory of the process.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from phid_ros.api import cut_scenarios, identify_cut  # noqa: E402
from phid_ros.ident import pipeline  # noqa: E402
from phid_ros.ident.constraints import parse_constraints  # noqa: E402
from phid_ros.ident.pipeline import IdentifyOptions  # noqa: E402
from phid_ros.io.bags.recordings import write_recording  # noqa: E402
from phid_ros.io.field.channel_map import load_channel_map  # noqa: E402
from phid_ros.io.field.pmu_csv import import_pmu_csv  # noqa: E402
from phid_ros.model.parameters import TABLE1  # noqa: E402
from test.io.field.field_sets import trend_log_set  # noqa: E402

SHOWN = ("X_d", "X_d_prime", "T_d0_prime")


def identify_once(bag: Path, check: bool) -> tuple[float, dict[str, tuple[float, bool]]]:
    """Wall time of one identification and its estimates (value, identified)."""
    saved = pipeline.MAX_FILES_LEFT_OUT
    pipeline.MAX_FILES_LEFT_OUT = saved if check else 0
    try:
        options = IdentifyOptions(baseline=False, validate=False, constraints=parse_constraints([f"X_q={TABLE1.X_q}"]))
        t0 = time.perf_counter()
        cut = cut_scenarios(bag)
        _, res = identify_cut([(cut.scenarios, cut.problems, str(bag))], options)
        wall = time.perf_counter() - t0
    finally:
        pipeline.MAX_FILES_LEFT_OUT = saved
    return wall, {n: (res.estimates[n].value, res.estimates[n].identifiable) for n in SHOWN}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        paths, cmap = trend_log_set(folder, TABLE1)
        bag = folder / "day.mcap"
        write_recording(bag, import_pmu_csv(paths, [load_channel_map(cmap)]))
        times: dict[bool, list[float]] = {True: [], False: []}
        found = {}
        for _ in range(args.runs):
            for check in (False, True):  # alternated: a noisy machine slows both alike
                wall, found[check] = identify_once(bag, check)
                times[check].append(wall)
    base, checked = statistics.median(times[False]), statistics.median(times[True])
    print(f"simulated trend-log day, {len(paths)} test files, medians of {args.runs} run(s):")
    print(f"  identify without the left-out check: {base:7.2f} s")
    print(f"  identify with each file left out:    {checked:7.2f} s   ({checked / base:.1f}x)")
    truth = {"X_d": TABLE1.X_d, "X_d_prime": TABLE1.X_d_prime, "T_d0_prime": TABLE1.T_d0_prime}
    for n in SHOWN:
        (a, ok_a), (b, ok_b) = found[False][n], found[True][n]
        print(
            f"  {n:11s} truth {truth[n]:.4g}: {a:.5g} ({'identified' if ok_a else 'withheld'}) / "
            f"{b:.5g} ({'identified' if ok_b else 'withheld'})"
        )
    print(f"peak memory {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()
