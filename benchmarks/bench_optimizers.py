"""The paper's optimiser comparison (Figs. 2-3) on the state-consistency objective.

    python benchmarks/bench_optimizers.py [--seeds 20] [--maxiter 100] [--window 6] [--out benchmarks/out]

Differential evolution (the paper's choice), dual annealing and basin hopping,
each with the same budget of objective evaluations, from different seeds; the
``fast`` variable-projection optimum is the reference line. Writes
``convergence.png`` (best J against evaluations, median over seeds) and
``boxplot.png`` (J* over seeds), and prints the table behind them.

To keep the study to minutes on 2 cores it uses the catalogue's identification
scenarios cut to ``--window`` seconds after the event and a reduced generation
count; the full-size comparison of DE against ``fast`` is bench_stage3.py.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import catalogue_scenarios  # noqa: E402

from phid_ros.ident import stage2, stage3  # noqa: E402

OPTIMIZERS = ("de", "dual_annealing", "basin_hopping")
_DATA: dict = {}


def _setup(window: float) -> None:
    scs = [s for s in catalogue_scenarios() if s.role == "identify"]
    r2 = stage2.identify_reactances(scs)
    _DATA["data"] = stage3.prepare(scs, window_s=window)
    _DATA["xd"], _DATA["xq"] = r2.X_d.value, r2.X_q.value


def _run(job: tuple[str, int, int, float]) -> tuple[str, int, float, float, int, list[tuple[int, float]]]:
    opt, seed, maxiter, window = job
    if "data" not in _DATA:
        _setup(window)
    t0 = time.perf_counter()
    r = stage3.global_search(
        _DATA["data"], _DATA["xd"], _DATA["xq"], seed=seed, maxiter=maxiter, optimizer=opt, starts=1
    )
    return opt, seed, r.objective, time.perf_counter() - t0, r.evaluations, r.history


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--maxiter", type=int, default=100, help="DE generations; the others get the same evaluations")
    ap.add_argument("--window", type=float, default=6.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "out"))
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    _setup(args.window)
    t0 = time.perf_counter()
    fast = stage3.variable_projection(_DATA["data"], _DATA["xd"], _DATA["xq"])
    t_fast = time.perf_counter() - t0
    jobs = [(opt, seed, args.maxiter, args.window) for opt in OPTIMIZERS for seed in range(args.seeds)]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        results = list(pool.map(_run, jobs))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    print(
        f"objective: {len(_DATA['data'].d.names)} scenarios, {args.window:g} s windows; "
        f"budget: DE {args.maxiter} generations x population 48, others the same evaluations"
    )
    print(f"fast: J* = {fast.objective:.8e} in {t_fast:.3f} s, {fast.evaluations} evaluations")
    print(
        f"{'optimizer':16s} {'median J*':>14s} {'min J*':>14s} {'max J*':>14s} {'J*/J_fast-1':>12s} "
        f"{'median s':>9s} {'evals':>7s}"
    )
    fig, ax = plt.subplots(figsize=(8, 5))
    box = []
    for opt in OPTIMIZERS:
        rs = [r for r in results if r[0] == opt]
        js = [r[2] for r in rs]
        box.append(js)
        med = statistics.median(js)
        print(
            f"{opt:16s} {med:14.8e} {min(js):14.8e} {max(js):14.8e} {med / fast.objective - 1:12.2e} "
            f"{statistics.median(r[3] for r in rs):9.2f} {int(statistics.median(r[4] for r in rs)):7d}"
        )
        grid = np.unique(np.geomspace(1, max(r[4] for r in rs), 200).astype(int))
        curves = []
        for r in rs:
            evals = np.array([h[0] for h in r[5]])
            best = np.array([h[1] for h in r[5]])
            pos = np.searchsorted(evals, grid, side="right") - 1
            curves.append(np.where(pos >= 0, best[np.clip(pos, 0, None)], np.nan))
        ax.plot(grid, np.nanmedian(np.array(curves), axis=0), label=opt)
    ax.axhline(fast.objective, color="k", ls=":", label=f"fast ({fast.evaluations} evaluations)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("objective evaluations")
    ax.set_ylabel("best J (median over seeds)")
    ax.set_title("Convergence of the state-consistency objective (cf. paper Fig. 2)")
    ax.legend()
    fig.savefig(out / "convergence.png", dpi=110, bbox_inches="tight")
    fig, ax = plt.subplots(figsize=(7, 5))
    ax.boxplot(box)
    ax.set_xticks(range(1, len(OPTIMIZERS) + 1), OPTIMIZERS)
    ax.axhline(fast.objective, color="k", ls=":", label="fast")
    ax.set_ylabel("final J*")
    ax.set_title(f"J* over {args.seeds} seeds (cf. paper Fig. 3)")
    ax.legend()
    fig.savefig(out / "boxplot.png", dpi=110, bbox_inches="tight")
    print(f"wrote {out / 'convergence.png'} and {out / 'boxplot.png'}")


if __name__ == "__main__":
    main()
