"""The missing-physics diagnosis: its hot path and the whole workflow on the shipped saturation bag.

    python benchmarks/bench_diagnose.py [--runs 5] [--whole 1]

1. The extended play-in on the six fit windows, with the saturation candidate added:
   one finite-difference Jacobian of the fit (eight base + two effect parameters, plus the
   centre: 11 models) computed as 11 columns of one vectorised run, against the baseline of
   11 separate runs (one model each, as a plain finite-difference loop over a simulator does).
2. A screening grid (the saturation joint screen: a few hundred models): all models in one
   run against the workflow's chunks (:func:`chi_square`), time and peak memory.
3. ``diagnose`` end to end (identification excluded) in one process and with a round's
   candidates in worker processes (every core), with the time split by phase from its
   progress messages, and its peak memory (traced in one more run; an end-to-end run takes minutes,
   so ``--whole`` defaults to one).

Figures are medians over ``--runs``; the machine is shared, so read the ratios.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import tracemalloc
from collections import defaultdict
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import ROOT, catalogue_scenarios, median_time  # noqa: E402

from phid_ros.cluster import default_workers  # noqa: E402
from phid_ros.diagnose.candidates import candidate  # noqa: E402
from phid_ros.diagnose.fit import SCREEN_CHUNK, ModelSpec, Problem, chi_square  # noqa: E402
from phid_ros.diagnose.options import DiagnoseOptions  # noqa: E402
from phid_ros.diagnose.trials import starting_point  # noqa: E402
from phid_ros.diagnose.windows import pre_event, split, window  # noqa: E402
from phid_ros.diagnose.workflow import diagnose  # noqa: E402
from phid_ros.ident.pipeline import IdentifyOptions, identify  # noqa: E402
from phid_ros.ident.plant_playin import OUTPUTS, play_in  # noqa: E402

BAG = ROOT / "bags" / "saturation"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--whole", type=int, default=1, help="end-to-end diagnoses to time")
    args = ap.parse_args()

    scs = catalogue_scenarios(BAG)
    res = identify(scs, IdentifyOptions(baseline=False, validate=False))
    start = res.parameters
    opt = DiagnoseOptions.after(res)  # as phid diagnose
    fit_s, _ = split(scs, opt.per_kind)
    windows = [window(s, opt.pre_s, opt.post_s) for s in fit_s]
    base = starting_point(start)[0]
    sat = candidate("magnetic_saturation")
    spec = ModelSpec(base, [(sat, {"s10": 0.07, "s12": 0.45})])
    problem = Problem(windows, {}, spec)
    x = problem.x0()
    X = x[:, None] + np.hstack([np.zeros((len(x), 1)), np.diag(1e-5 * np.maximum(1.0, np.abs(x)))])
    m = X.shape[1]
    steps = sum(w.n for w in windows)
    print(f"bags/saturation: {len(windows)} fit windows, {steps} samples, {m} models per Jacobian")

    t_vec, _ = median_time(lambda: problem.residual_matrix(X), args.runs)
    t_loop, _ = median_time(lambda: [problem.residual_matrix(X[:, [j]]) for j in range(m)], args.runs)
    print(
        f"  Jacobian, {m} columns in one run: median {t_vec:.3f} s; "
        f"{m} separate runs: {t_loop:.3f} s; ratio {t_loop / t_vec:.1f}x"
    )

    values, trial_base = sat.joint_screen(base, pre_event(windows))  # type: ignore[misc]
    n = len(values["s10"])
    effects = [(sat.effect, values)]
    sigma = {c: 1.0 for c in OUTPUTS}
    reps = max(1, args.runs // 2)
    t_one, _ = median_time(lambda: play_in(windows, trial_base, effects, m=n), reps)
    t_chunk, _ = median_time(lambda: chi_square(windows, sigma, trial_base, effects, n), reps)
    mem_one = _peak_mb(lambda: play_in(windows, trial_base, effects, m=n))
    mem_chunk = _peak_mb(lambda: chi_square(windows, sigma, trial_base, effects, n))
    print(f"  saturation joint screen, {n} models (one model alone: {1e3 * t_loop / m:.0f} ms):")
    print(
        f"    all in one run:        median {t_one:.2f} s ({1e3 * t_one / n:.1f} ms per model), peak {mem_one:.0f} MB"
    )
    print(
        f"    chunks of {SCREEN_CHUNK} (chi_square): median {t_chunk:.2f} s ({1e3 * t_chunk / n:.1f} ms per model), "
        f"peak {mem_chunk:.0f} MB"
    )

    whole: dict[int, float] = {}
    for workers in (1, 0):
        totals: list[float] = []
        phases: defaultdict[str, list[float]] = defaultdict(list)
        for _ in range(args.whole):
            marks: list[tuple[float, str]] = []
            t0 = time.perf_counter()
            d = diagnose(
                scs,
                start,
                replace(opt, workers=workers),
                progress=lambda msg: marks.append((time.perf_counter(), msg)),
            )
            t1 = time.perf_counter()
            totals.append(t1 - t0)
            spent: dict[str, float] = defaultdict(float)
            for (ta, msg), (tb, _) in zip(marks, marks[1:] + [(t1, "")]):
                spent[msg.split(" ")[0]] += tb - ta
            for k, v in spent.items():
                phases[k].append(v)
        how = "one process" if workers == 1 else f"{default_workers()} worker processes"
        print(
            f"  diagnose end to end, {how} ({args.whole} run(s)): "
            f"median {statistics.median(totals):.1f} s, named {d.named}"
        )
        for k, spans in sorted(phases.items(), key=lambda kv: -statistics.median(kv[1])):
            print(f"    {k:10s} median {statistics.median(spans):6.1f} s")
        whole[workers] = statistics.median(totals)
    print(f"  worker processes against one: {whole[1] / whole[0]:.2f}x")
    peak = _peak_mb(lambda: diagnose(scs, start, opt))
    print(f"  diagnose peak traced memory, one process (one more run): {peak:.0f} MB")


def _peak_mb(fn: Callable[[], object]) -> float:
    """Peak memory allocated while ``fn`` runs (numpy reports its buffers to tracemalloc)."""
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


if __name__ == "__main__":
    main()
