"""Fleet throughput on Dask: recordings per minute for 1 and 2 local workers, against a plain loop.

    python benchmarks/bench_fleet.py [--recordings 8] [--runs 3] [--inventory DIR]

1. Baseline: the same task (``process_recording``: read, three-stage identification,
   validation) in a plain Python loop in this process, no Dask.
2. ``run_fleet`` on a LocalCluster of 1 and of 2 worker processes, each on a fresh fleet
   folder: throughput from the first submission to the last stored row, and the ratio to
   the baseline. Start-up (the cluster, and each worker importing phid, which a long fleet
   run pays once) is printed apart. The baseline's process is warm after its first run,
   and the median of ``--runs`` is taken, so both sides compare warm.
3. Scheduling overhead per task: 400 empty tasks through the two-worker cluster.
4. Memory: RSS of the largest worker after its tasks, peak RSS of this process.
5. Extrapolation: units a cluster of N workers serves at one recording per unit per day,
   from the measured per-worker throughput (a linear model; the scheduler's per-task
   cost bounds it far above these figures).

Recordings: ``--recordings`` short catalogue runs (6 s windows, 18 scenarios, ~2.9 MB each,
the size of the fleet test's) spread over units, simulated into a temporary folder unless
``--inventory`` names one. Figures are medians over ``--runs``; the machine is shared, so
read the ratios.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from phid_ros.fleet.inventory import discover  # noqa: E402
from phid_ros.fleet.run import FleetOptions, run_fleet  # noqa: E402
from phid_ros.fleet.task import process_recording  # noqa: E402
from phid_ros.io.files.digest import content_hash, recording_files  # noqa: E402


def make_inventory(root: Path, n: int) -> None:
    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.sim.recording import DEFAULT_START_NS, recording_from_runs
    from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
    from phid_ros.sim.scenarios import paper_catalogue
    from phid_ros.sim.sensors import SensorModel

    catalogue = [replace(s, duration=6.0) for s in paper_catalogue()]
    for k in range(n):
        cfg = SimulationConfig(restore_ramp=1.0, restore_hold=1.0, sensors=SensorModel(seed=100 + k))
        rec = recording_from_runs(
            simulate_scenarios(catalogue, cfg), cfg, start_ns=DEFAULT_START_NS + k * 86_400 * 10**9
        )
        unit = root / f"U{k % 4 + 1}"
        unit.mkdir(parents=True, exist_ok=True)
        write_recording(unit / f"rec{k:02d}.mcap", rec)


def worker_rss_mb(client: object) -> float:
    import psutil

    rss = client.run(lambda: psutil.Process().memory_info().rss)  # type: ignore[attr-defined]
    return max(rss.values()) / 2**20


def fleet_once(inventory: Path, workers: int) -> tuple[float, float, float]:
    """(seconds for the tasks, cluster start-up seconds, largest worker RSS MB after the tasks)."""
    marks: dict[str, float] = {}
    clients: list[object] = []
    rss: list[float] = []

    def on_cluster(client: object) -> None:
        marks["cluster"] = time.perf_counter()
        clients.append(client)

    def on_row(row: object, done: int, total: int) -> None:
        marks["last"] = time.perf_counter()
        if done == total:
            rss.append(worker_rss_mb(clients[0]))

    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        options = FleetOptions(workers=workers, dashboard=False)
        res = run_fleet(inventory, Path(out) / "fleet", options, on_cluster=on_cluster, on_row=on_row)
    bad = [r.error for r in res.rows if r.status != "ok"]
    if bad:
        raise SystemExit(f"a fleet task failed: {bad[0]}")
    return marks["last"] - marks["cluster"], marks["cluster"] - t0, rss[0]


def overhead_per_task_ms(n: int = 400) -> float:
    from phid_ros.cluster import cluster

    with cluster(workers=2) as client:
        client.gather(client.map(abs, range(10), pure=False))  # warm
        t0 = time.perf_counter()
        client.gather(client.map(abs, range(n), pure=False))
        dt = time.perf_counter() - t0
    return 1e3 * dt / n


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--recordings", type=int, default=8)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--inventory", type=Path)
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        inventory = args.inventory
        if inventory is None:
            inventory = Path(tmp) / "inventory"
            t0 = time.perf_counter()
            make_inventory(inventory, args.recordings)
            print(f"simulated {args.recordings} recordings in {time.perf_counter() - t0:.1f} s")
        items, _ = discover(inventory)
        n = len(items)
        print(f"{n} recordings of {len({i.unit for i in items})} units, {os.cpu_count()} cores")

        base, spans = [], []
        for _ in range(args.runs):
            t0 = time.perf_counter()
            for it in items:
                row = process_recording(it.unit, str(it.path), content_hash(it.path))
                assert row.status == "ok", row.error
                assert row.start_ns is not None and row.end_ns is not None
                spans.append((row.end_ns - row.start_ns) / 1e9)
            base.append(time.perf_counter() - t0)
        size = statistics.mean(sum(f.stat().st_size for f in recording_files(it.path)) for it in items) / 2**20
        print(f"a recording: {statistics.mean(spans):.0f} s of data, {size:.1f} MB (the units figures scale with this)")
        t_base = statistics.median(base)
        rpm_base = 60 * n / t_base
        print(f"baseline, plain loop in one process: {t_base:.1f} s, {rpm_base:.1f} recordings/min")

        per_worker: dict[int, float] = {}
        for workers in (1, 2):
            runs = [fleet_once(inventory, workers) for _ in range(args.runs)]
            t_tasks = statistics.median(r[0] for r in runs)
            t_start = statistics.median(r[1] for r in runs)
            worker_mb = max(r[2] for r in runs)
            rpm = 60 * n / t_tasks
            per_worker[workers] = rpm / workers
            print(
                f"dask, {workers} worker(s): {t_tasks:.1f} s for the tasks ({rpm:.1f} recordings/min, "
                f"{rpm / rpm_base:.2f}x the loop), cluster start-up {t_start:.1f} s, largest worker {worker_mb:.0f} MB"
            )
        ratio = per_worker[2] * 2 / per_worker[1]
        print(f"2 workers vs 1: {ratio:.2f}x")

        ms = overhead_per_task_ms()
        print(f"scheduling overhead: {ms:.2f} ms per task (400 empty tasks, 2 workers)")
        driver = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"memory: peak RSS of this process (it also ran the baseline loop) {driver:.0f} MB")

        rate = per_worker[2]  # recordings per minute per worker, measured with two
        for n_workers in (2, 8, 32, 128):
            print(
                f"  {n_workers:4d} workers: ~{rate * n_workers * 1440:,.0f} units at one recording per unit per day "
                f"(linear in workers; scheduler cost {ms:.1f} ms/task caps it near {86_400_000 / ms:,.0f} tasks/day)"
            )


if __name__ == "__main__":
    main()
