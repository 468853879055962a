"""The speed goals of one release against a baseline revision, measured in the same run.

    python benchmarks/bench_speed.py [--baseline REV] [--runs 5] [--skip-diagnose]

The baseline's code is checked out into a temporary git worktree and each figure is
measured for it and for this tree alternately (so a machine that gets busier part way
hurts both alike). Each figure is a median over ``--runs`` (diagnose: over 1 run unless
``--diagnose-runs`` says more, it takes minutes). Printed per goal: baseline, this tree,
ratio, and the goal.

- identify warm: the median of repeated read + identify + JSON in one process (the first run
  left out), in three processes a tree;
- identify fresh: ``phid identify BAG --json`` in a new process (interpreter start included),
  wall and CPU seconds (user + system: the same work, less moved by the machine's other tenants);
- replay: ``phid replay bags/catalogue``, stream seconds per wall second, and CPU seconds;
- diagnose: ``phid diagnose bags/saturation`` end to end, wall time and peak memory (the sum
  over the command and its Dask worker processes, sampled every 0.2 s from /proc); and as on a
  machine's first run, numba's cache empty (``NUMBA_CACHE_DIR`` a new directory each run): what a
  new user waits for, the kernels' compile included;
- diagnose CSV: ``phid diagnose`` of a 16-scenario x 30 s CSV set with saturation hidden,
  made by this tree's ``phid simulate --out DIR/manifest.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BAGS = ROOT / "bags"

WARM_IDENTIFY = """
import json, statistics, sys, time
from pathlib import Path
from phid_ros.cli.main import main
import contextlib, io
bag, out, runs = sys.argv[1], sys.argv[2], int(sys.argv[3])
times = []
for _ in range(runs + 1):
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        main(["identify", bag, "--json", out])
    times.append(time.perf_counter() - t0)
print(json.dumps({"warm": statistics.median(times[1:])}))
"""


def _env(tree: Path, extra: dict[str, str] | None = None) -> dict[str, str]:
    env = dict(os.environ) | (extra or {})
    env["PYTHONPATH"] = str(tree)
    # as a pip-installed package runs (pip compiles the bytecode): a sandbox that sets this made
    # every fresh process compile all of phid_ros from source, in both trees
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _tree_rss_mb(root: int) -> float:
    """Resident memory of a process and all its descendants (MB), from /proc (Linux)."""
    parent: dict[int, int] = {}
    rss: dict[int, int] = {}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parent[int(d.name)] = int(fields[1])
        rss[int(d.name)] = int(fields[21]) * os.sysconf("SC_PAGE_SIZE")
    tree, todo = set(), [root]
    while todo:
        p = todo.pop()
        tree.add(p)
        todo.extend(c for c, pp in parent.items() if pp == p and c not in tree)
    return sum(rss.get(p, 0) for p in tree) / 2**20


def _timed(
    cmd: list[str], tree: Path, sample_tree: bool = False, env: dict[str, str] | None = None
) -> tuple[float, float, str, float]:
    """Wall seconds, peak memory (MB), stdout and CPU seconds (user + system) of a child.

    Peak memory: the child's own (wait4), or with ``sample_tree`` the largest sum over the
    child and its descendants (Dask workers), sampled every 0.1 s. CPU: the child's and its
    reaped descendants'; steadier than wall time on a shared machine whose other tenants come
    and go (wall medians of one tree moved 1.4-2.4 s within minutes).
    """
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, env=_env(tree, env), stdout=out, stderr=err, text=True, cwd=tree)
        if sample_tree:
            peak = 0.0
            while proc.poll() is None:
                peak = max(peak, _tree_rss_mb(proc.pid))
                time.sleep(0.1)
            wall = time.perf_counter() - t0
        else:
            _, status, usage = os.wait4(proc.pid, 0)
            wall = time.perf_counter() - t0
            proc.returncode = os.waitstatus_to_exitcode(status)
            peak = usage.ru_maxrss / 1024
        out.seek(0)
        err.seek(0)
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed in {tree}:\n{err.read()[-2000:]}")
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        return wall, peak, out.read(), cpu


def identify_warm(tree: Path, runs: int, tmp: Path) -> float:
    _, _, out, _ = _timed(
        [sys.executable, "-c", WARM_IDENTIFY, str(BAGS / "catalogue"), str(tmp / "w.json"), str(runs)], tree
    )
    return float(json.loads(out.strip().splitlines()[-1])["warm"])


def identify_fresh(tree: Path, tmp: Path) -> tuple[float, float]:
    """Wall and CPU seconds."""
    cmd = [
        sys.executable,
        "-m",
        "phid_ros.cli.main",
        "identify",
        str(BAGS / "catalogue"),
        "--json",
        str(tmp / "f.json"),
    ]
    wall, _, _, cpu = _timed(cmd, tree)
    return wall, cpu


def replay_speed(tree: Path, tmp: Path) -> tuple[float, float]:
    """Stream seconds per wall second, and CPU seconds."""
    out = tmp / "replay.mcap"
    cmd = [sys.executable, "-m", "phid_ros.cli.main", "replay", str(BAGS / "catalogue"), "--out", str(out), "--force"]
    wall, _, _, cpu = _timed(cmd, tree)
    return 660.0 / wall, cpu  # the catalogue holds 660 s of data; start-up and writing included


def diagnose(tree: Path, tmp: Path, data: Path, first_run: bool = False) -> tuple[float, float]:
    """Wall time and peak memory of all its processes (the candidates run in Dask workers);
    ``first_run``: with numba's cache in a new, empty directory (every kernel compiled)."""
    cmd = [sys.executable, "-m", "phid_ros.cli.main", "diagnose", str(data), "--json", str(tmp / "d.json")]
    env = {"NUMBA_CACHE_DIR": tempfile.mkdtemp(prefix="numba-", dir=tmp)} if first_run else None
    wall, peak, _, _ = _timed(cmd, tree, sample_tree=True, env=env)
    return wall, peak


def csv_set(tmp: Path) -> Path:
    """16 scenarios x 30 s with saturation hidden, as a CSV scenario set (this tree's phid simulate)."""
    names = [f"S{i:02d}" for i in range(1, 14)] + ["V1", "V2", "V3"]
    manifest = tmp / "csv16" / "manifest.json"
    cmd = [sys.executable, "-m", "phid_ros.cli.main", "simulate", "--duration", "30", "--out", str(manifest)]
    cmd += [a for n in names for a in ("--scenario", n)]
    cmd += ["--effect", "magnetic_saturation=s10=0.08,s12=0.35"]
    _timed(cmd, ROOT)
    return manifest


def _worktree(rev: str, where: Path) -> Path:
    path = where / "baseline"
    subprocess.run(
        ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(path), rev], check=True, capture_output=True
    )
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="389835a", help="git revision to compare with (default: before issue 17)")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--diagnose-runs", type=int, default=1)
    ap.add_argument("--skip-diagnose", action="store_true", help="leave out the minutes-long diagnosis")
    ap.add_argument("--diagnose-only", action="store_true", help="only the diagnosis figures")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        base = _worktree(args.baseline, tmp)
        trees = {"baseline": base, "this tree": ROOT}
        try:
            figures: dict[str, dict[str, list[float]]] = {name: {} for name in trees}

            def add(tree: str, key: str, value: float) -> None:
                figures[tree].setdefault(key, []).append(value)

            if not args.diagnose_only:
                for _ in range(3):  # three warm processes a tree, alternately: the machine drifts
                    for name, tree in trees.items():
                        add(name, "identify warm (s)", identify_warm(tree, args.runs, tmp))
                for _ in range(args.runs):
                    for name, tree in trees.items():
                        wall, cpu = identify_fresh(tree, tmp)
                        add(name, "identify fresh (s)", wall)
                        add(name, "identify fresh CPU (s)", cpu)
                        speed, cpu = replay_speed(tree, tmp)
                        add(name, "replay (x real time)", speed)
                        add(name, "replay CPU (s)", cpu)
            if not args.skip_diagnose:
                manifest = csv_set(tmp)
                for _ in range(args.diagnose_runs):
                    for name, tree in trees.items():
                        wall, peak = diagnose(tree, tmp, BAGS / "saturation")
                        add(name, "diagnose saturation (s)", wall)
                        add(name, "diagnose peak memory (MB)", peak)
                        add(name, "diagnose CSV 16x30 s (s)", diagnose(tree, tmp, manifest)[0])
                        first = diagnose(tree, tmp, BAGS / "saturation", first_run=True)[0]
                        add(name, "diagnose saturation, first run (s)", first)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)], check=False)
    goals = {
        "identify warm (s)": "≤ 0.2",
        "identify fresh (s)": "≤ 0.5",
        "identify fresh CPU (s)": "(the same work, steadier)",
        "replay (x real time)": "≥ 500",
        "replay CPU (s)": "(the same work, steadier)",
        "diagnose saturation (s)": "≤ 15",
        "diagnose peak memory (MB)": "≤ 400",
        "diagnose CSV 16x30 s (s)": "≤ 60",
        "diagnose saturation, first run (s)": "< 60 (issue 52: with the README's install)",
    }
    print(f"baseline {args.baseline} vs this tree; medians of {args.runs} runs (diagnose: {args.diagnose_runs})")
    print(f"{'figure':36s} {'baseline':>10s} {'this tree':>10s} {'ratio':>7s}   goal")
    for key, goal in goals.items():
        if key not in figures["baseline"]:
            continue
        b = statistics.median(figures["baseline"][key])
        n = statistics.median(figures["this tree"][key])
        ratio = n / b if "real time" in key else b / n  # > 1: faster (or smaller)
        print(f"{key:36s} {b:10.3f} {n:10.3f} {ratio:6.2f}x   {goal}")


if __name__ == "__main__":
    main()
