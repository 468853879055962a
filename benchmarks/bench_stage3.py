"""Stage 3 on the shipped catalogue bag: ``fast`` (variable projection) vs ``paper`` (DE 12 x 300).

    python benchmarks/bench_stage3.py [--repeats 5] [--paper-maxiter 300]

Prints wall time, objective evaluations and final J of both methods and their ratio.
Both optimise the same objective J with X_d, X_q fixed from stage 2.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import catalogue_scenarios, median_time  # noqa: E402

from phid_ros.ident import stage2, stage3  # noqa: E402
from phid_ros.model.parameters import TABLE1  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--paper-maxiter", type=int, default=300)
    args = ap.parse_args()
    scs = [s for s in catalogue_scenarios() if s.role == "identify"]
    r2 = stage2.identify_reactances(scs)
    xd, xq = r2.X_d.value, r2.X_q.value
    t_prep, data = median_time(lambda: stage3.prepare(scs), args.repeats)
    t_fast, fast = median_time(lambda: stage3.variable_projection(data, xd, xq), args.repeats)
    t0 = time.perf_counter()
    paper = stage3.global_search(data, xd, xq, maxiter=args.paper_maxiter, seed=0)
    t_paper = time.perf_counter() - t0
    print(f"scenarios: {len(scs)}; X_d = {xd:.5f}, X_q = {xq:.5f} from stage 2; prepare {t_prep * 1e3:.1f} ms")
    print(f"{'method':8s} {'wall s':>9s} {'evals':>7s} {'J':>14s}   X'_d      X'_q      T'_d0     T'_q0")
    for name, r, t in (("fast", fast, t_fast), ("paper", paper, t_paper)):
        vals = [getattr(r, n).value for n in ("X_d_prime", "X_q_prime", "T_d0_prime", "T_q0_prime")]
        print(f"{name:8s} {t:9.3f} {r.evaluations:7d} {r.objective:14.8e}   " + "  ".join(f"{v:.5f}" for v in vals))
    truth = [TABLE1.X_d_prime, TABLE1.X_q_prime, TABLE1.T_d0_prime, TABLE1.T_q0_prime]
    print(f"J at the true parameters: {stage3.objective(data, truth, xd, xq):.8e}")
    print(
        f"ratio: fast is {t_paper / t_fast:.0f}x faster (wall, fast median of {args.repeats}), "
        f"{paper.evaluations / fast.evaluations:.0f}x fewer evaluations; "
        f"J_fast - J_paper = {fast.objective - paper.objective:+.3e} "
        f"({'fast lower or equal' if fast.objective <= paper.objective * (1 + 1e-9) else 'paper lower'})"
    )


if __name__ == "__main__":
    main()
