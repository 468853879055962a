"""Field recordings in: COMTRADE and PMU imports against a CSV import of the same scenarios.

    python benchmarks/bench_import.py [--runs 3] [--scenarios 18]

Makes the catalogue's scenarios (12 s at 1 kHz) as three sets of one recording each: binary
COMTRADE (six waveforms and six value channels), ASCII COMTRADE, and the CSV scenario set of
the same phasors; then times each import (median over ``--runs``) and prints the ratio to
the CSV import. Also times the phasor step alone: the sliding one-cycle DFT by cumulative sums
(``phid_ros.io.field.phasors``) against a direct per-window DFT (``np.convolve`` per phase), and
prints the peak resident memory of the process.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from phid_ros.io.csvset.csv_export import write_csv_set  # noqa: E402
from phid_ros.io.csvset.csv_import import import_csv_set  # noqa: E402
from phid_ros.io.field.channel_map import load_channel_map  # noqa: E402
from phid_ros.io.field.comtrade_import import import_comtrade  # noqa: E402
from phid_ros.io.field.phasors import positive_sequence  # noqa: E402
from phid_ros.sim.recording import recording_from_runs  # noqa: E402
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios  # noqa: E402
from phid_ros.sim.scenarios import paper_catalogue, with_duration  # noqa: E402
from test.io.field.comtrade_writer import write_comtrade  # noqa: E402
from test.io.field.test_comtrade_import import MAP, waveforms  # noqa: E402


def median(fn, runs: int) -> float:
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def direct_dft(xa: np.ndarray, xb: np.ndarray, xc: np.ndarray, n: int) -> np.ndarray:
    """The textbook sliding DFT: one convolution per phase with the cycle's complex kernel."""
    a = np.exp(2j * np.pi / 3)
    k = np.arange(len(xa))
    out = []
    for x in (xa, xb, xc):
        y = x * np.exp(-2j * np.pi * k / n)
        out.append(np.sqrt(2.0) / n * np.convolve(y, np.ones(n), mode="valid"))
    return (out[0] + a * out[1] + a**2 * out[2]) / 3.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--scenarios", type=int, default=18)
    args = ap.parse_args()
    scenarios = [with_duration(s, 12.0) for s in paper_catalogue()][: args.scenarios]
    cfg = SimulationConfig()
    runs = simulate_scenarios(scenarios, cfg)
    rng = np.random.default_rng(5)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        sets: dict[str, list[Path]] = {"binary": [], "ascii": []}
        for run in runs:
            n = run.n_analysis
            w = waveforms({c: x[:n] for c, x in run.measured.items()}, rng)
            for kind in sets:
                (folder / kind).mkdir(exist_ok=True)
                path = folder / kind / f"{run.scenario.name}.cfg"
                sets[kind].append(write_comtrade(path, w, 1000.0, ft=kind.upper()))
        (folder / "map.yaml").write_text(MAP)
        cmap = load_channel_map(folder / "map.yaml")
        manifest = write_csv_set(folder / "csv", recording_from_runs(runs, cfg))
        samples = sum(r.n_analysis for r in runs)
        t_csv = median(lambda: import_csv_set(manifest), args.runs)
        t_bin = median(lambda: import_comtrade(sets["binary"], cmap), args.runs)
        t_asc = median(lambda: import_comtrade(sets["ascii"], cmap), args.runs)
    xa, xb, xc = (np.cos(2 * np.pi * 50 * np.arange(samples) / 1000.0 - 2 * np.pi * k / 3) for k in range(3))
    t_dft = median(lambda: positive_sequence(xa, xb, xc, 20), args.runs)
    t_direct = median(lambda: direct_dft(xa, xb, xc, 20), args.runs)
    assert np.allclose(positive_sequence(xa, xb, xc, 20), direct_dft(xa, xb, xc, 20), atol=1e-9)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{len(runs)} scenarios x 12 s at 1 kHz ({samples} samples each of 12 channels), median of {args.runs}")
    print(f"  CSV set import (baseline)     {t_csv:7.2f} s")
    print(f"  COMTRADE binary import        {t_bin:7.2f} s   {t_bin / t_csv:5.2f}x the CSV import")
    print(f"  COMTRADE ASCII import         {t_asc:7.2f} s   {t_asc / t_csv:5.2f}x the CSV import")
    ratio = t_direct / t_dft
    print(f"  phasors, cumulative-sum DFT   {t_dft:7.3f} s   direct per-window DFT {t_direct:.3f} s ({ratio:.1f}x)")
    print(f"  peak resident memory          {peak:7.0f} MB")


if __name__ == "__main__":
    main()
