"""Our own algorithms against the library each stands in for: is keeping it worth it?

    python benchmarks/bench_own_code.py [--runs 7]

Three places where phid runs its own code instead of calling a library, each timed against
that library on the same input (median of ``--runs``), with the largest difference of the
results, so that a ratio is never bought with a different answer:

1. stage 3's first-order-hold filter at the kept samples (``numerics.first_order_response_kept``,
   compiled with numba where installed) and the second-order low-pass's all-pole recursion
   (``numerics.all_pole``) against ``scipy.signal.lfilter``;
2. the batched CDR decoding of equally long sensor blocks (``io.cdr_blocks.decode_group``)
   against rosbags' ``deserialize_cdr`` one message at a time;
3. the MCAP walk (``io.mcap_raw.iter_messages``: chunk decompression ahead on threads) against
   the ``mcap`` package's reader, over the shipped catalogue bag.

Prints each pair's medians, the ratio (library / ours: above 1, ours is faster) and the peak
resident memory of the process at the end.

A fourth, stage 1's own Levenberg-Marquardt envelope fit, was measured here against
``scipy.optimize.curve_fit(method="lm")`` on 200 speed-oscillation envelopes on 2026-11-25:
64 ms against 24 ms (x0.37), the same optimum to 1.2e-7. It lost, and stage 1 calls
curve_fit again.
"""

from __future__ import annotations

import argparse
import resource
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import scipy.signal

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import median_time  # noqa: E402

from phid_ros import jit  # noqa: E402
from phid_ros.io.bags.cdr_blocks import decode_group  # noqa: E402
from phid_ros.io.bags.mcap_raw import iter_messages  # noqa: E402
from phid_ros.io.msg_schemas import typestore  # noqa: E402
from phid_ros.numerics import all_pole, first_order_coefficients, first_order_response_kept  # noqa: E402

BAG = ROOT / "bags" / "catalogue" / "catalogue.mcap"


def row(what: str, ours: float, lib: float, diff: float) -> None:
    times = f"ours {ours * 1e3:9.3f} ms   library {lib * 1e3:9.3f} ms   x{lib / ours:5.2f}"
    print(f"  {what:44s} {times}   max |diff| {diff:.1e}")


def bench_filters(runs: int) -> None:
    rng = np.random.default_rng(1)
    u = np.cumsum(rng.standard_normal((15, 13_000)), axis=1)  # a stage-3 block: 15 rows of 13 s at 1 kHz
    tau, dt, step = 0.37, 1e-3, 5
    a, b0, b1 = first_order_coefficients(tau, dt)

    def library_foh() -> np.ndarray:
        y = scipy.signal.lfilter([b1, b0], [1.0, -a], u, axis=1)
        y -= b1 * u[:, :1] * a ** np.arange(u.shape[1])  # x(0) = 0: lfilter would count u[0]'s b1 term
        return y[:, ::step]

    t_ours, got = median_time(lambda: first_order_response_kept(u, tau, dt, step), runs * 20)
    t_lib, want = median_time(library_foh, runs * 20)
    row("first-order hold, kept samples (15 x 13000)", t_ours, t_lib, float(np.max(np.abs(got - want))))

    coef = (-1.9, 0.905)  # a critically damped second-order low-pass's denominator
    x = rng.standard_normal((13_000, 15))
    t_ours, got = median_time(lambda: all_pole(x, coef, axis=0), runs * 20)
    t_lib, want = median_time(lambda: scipy.signal.lfilter([1.0], [1.0, *coef], x, axis=0), runs * 20)
    row("all-pole recursion, 2nd order (13000 x 15)", t_ours, t_lib, float(np.max(np.abs(got - want))))


def bench_cdr(runs: int) -> None:
    raws = [bytes(raw) for topic, _, _, raw in iter_messages(BAG) if topic.endswith("/pt_ct")]
    store = typestore()
    msgtype = "phid_msgs/msg/PtCtBlock"
    channels = ("v_t", "i_d", "i_q", "p_e", "q_e")

    def ours() -> np.ndarray:
        dec = decode_group(raws, np.arange(len(raws)), None, len(channels))
        assert dec is not None
        return np.stack(dec.values)

    def library() -> np.ndarray:
        msgs = [store.deserialize_cdr(r, msgtype) for r in raws]
        return np.stack([np.stack([getattr(m, c) for m in msgs]) for c in channels])

    t_ours, a = median_time(ours, runs)
    t_lib, b = median_time(library, runs)
    row(f"CDR decoding, {len(raws)} PtCtBlock messages", t_ours, t_lib, float(np.max(np.abs(a - b))))


def bench_mcap_walk(runs: int) -> None:
    from mcap.reader import make_reader

    def ours() -> int:
        return sum(len(raw) for _, _, _, raw in iter_messages(BAG))

    def library() -> int:
        with BAG.open("rb") as f:
            return sum(len(m.data) for _, _, m in make_reader(f).iter_messages(log_time_order=False))

    t_ours, a = median_time(ours, runs)
    t_lib, b = median_time(library, runs)
    assert a == b, (a, b)
    row(f"MCAP walk, {BAG.stat().st_size / 2**20:.1f} MB catalogue bag", t_ours, t_lib, 0.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7)
    args = ap.parse_args()
    print(f"own code against the library it stands in for, median of {args.runs} (filters: of {args.runs * 20})")
    print(f"numba {'on' if jit.available() else 'off'}")
    steps: list[Callable[[int], None]] = [bench_filters, bench_cdr, bench_mcap_walk]
    for step in steps:
        step(args.runs)
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()
