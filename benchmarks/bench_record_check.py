"""The cost of checking the unit's record on file at every event (issue 74).

    python benchmarks/bench_record_check.py [--repeats 5]

Replays the shipped catalogue (18 events, 660 s) through the monitor pipeline without a record
and with the machine's own record (written as ``phid export`` writes it), alternating the two
in each repeat, and prints: the medians of wall time and of x real time, their ratio, the
record's cost per event checked (its median), and the peak resident memory of each (measured
in a fresh process each, since ``ru_maxrss`` never goes down).
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import CATALOGUE  # noqa: E402

from phid_ros.model.conventions import NS  # noqa: E402


def own_record(folder: Path, x_d_prime_scale: float = 1.0, name: str = "own") -> Path:
    """The catalogue machine's record as ``phid export`` writes it (operating point P_m0 0.8);
    with ``x_d_prime_scale``, a record of the wrong machine."""
    from phid_ros.cli.main import main
    from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1

    params = TABLE1.replace(X_d_prime=x_d_prime_scale * TABLE1.X_d_prime)
    doc = {
        "parameters": params.as_dict(),
        "identifiable": {n: True for n in PARAMETER_NAMES},
        "f_nominal_hz": 50.0,
        "base_mva": 1000.0,
        "operating_point": {"p_m_pu": 0.8},
    }
    (folder / f"{name}.json").write_text(json.dumps(doc))
    out = folder / f"{name}.dyr"
    main(["export", str(folder / f"{name}.json"), "--format", "psse-dyr", "--out", str(out)])
    return out


def one_replay(record: str | None) -> tuple[float, int, float]:
    """(wall s, events checked, seconds in the record's play-in) of one replay."""
    from phid_ros.api import record_check
    from phid_ros.io.bags.recordings import read_recording
    from phid_ros.stream.pipeline import MonitorPipeline
    from phid_ros.stream.replay import replay

    rec = read_recording(CATALOGUE)
    pipeline = MonitorPipeline()
    spent = [0.0]
    if record:
        check = record_check(record)
        play = check.play

        def timed(scenarios: Any, f_hz: float) -> Any:
            t0 = time.perf_counter()
            try:
                return play(scenarios, f_hz)
            finally:
                spent[0] += time.perf_counter() - t0

        check.play = timed
        pipeline.record_check = check
    t0 = time.perf_counter()
    out = replay(rec, pipeline)
    wall = time.perf_counter() - t0
    pipeline.close()
    return wall, len(out.verdicts), spent[0]


def peak_mb(record: str | None) -> float:
    """Peak resident memory of one replay in a process of its own."""
    code = (
        "import sys, resource; sys.path.insert(0, sys.argv[1]); import bench_record_check as b; "
        "b.one_replay(sys.argv[2] or None); print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)"
    )
    here = str(Path(__file__).resolve().parent)
    out = subprocess.run([sys.executable, "-c", code, here, record or ""], capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    from phid_ros.io.bags.recordings import read_recording

    start, end = read_recording(CATALOGUE).span_ns()
    span = (end - start) / NS
    with tempfile.TemporaryDirectory() as tmp:
        record = str(own_record(Path(tmp)))
        one_replay(record)  # compiled once, outside the timing
        bare, checked, per_event = [], [], []
        for _ in range(args.repeats):
            bare.append(one_replay(None)[0])
            wall, n, spent = one_replay(record)
            checked.append(wall)
            per_event.append(spent / max(n, 1))
        mem_bare, mem_checked = peak_mb(None), peak_mb(record)
    b, c = statistics.median(bare), statistics.median(checked)
    print(f"catalogue replay ({span:.0f} s, {args.repeats} repeats, medians)")
    print(f"  without a record: {b:.2f} s wall ({span / b:.0f}x real time), peak {mem_bare:.0f} MB")
    print(f"  with the record:  {c:.2f} s wall ({span / c:.0f}x real time), peak {mem_checked:.0f} MB")
    each = 1e3 * statistics.median(per_event)
    print(f"  ratio with / without: {c / b:.2f}; the record's play-in {each:.0f} ms an event")
    print(f"  this process's peak: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()
