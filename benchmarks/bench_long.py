"""Long recordings: peak memory and throughput of each command against the recording's length.

    python benchmarks/bench_long.py [--hours 0.5 2 24] [--baseline ada499f] [--out benchmarks/out/long]

For each length an ambient recording (``phid simulate --ambient``: load and voltage noise with
small steps, 1 kHz) is made once, then ``phid replay``, ``phid identify``, ``phid track`` and
``phid info`` (and ``phid validate`` of the simulated machine's record) run on it, each in its
own process under ``/usr/bin/time`` (peak resident memory,
wall time), with this tree and, where ``--baseline`` names a revision, with that revision
checked out beside it (a git worktree) in the same run: the ratios are measured on the same
machine at the same time. ``read`` is the limit a replay can reach: walking and decoding the
same bag alone (part by part). The baseline is not run where its memory would exceed
``--baseline-max-gb`` (0.5 GB per hour of replay on ada499f: 24 h would need ~45 GB).

Issue 39's goals: at most 1.2 GB for 2 h and for 24 h; replay at least 400x real time on 2 h
and not slower per hour on 24 h.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# every part read and let go (a list of them would hold the whole recording again)
READ = (
    "import sys, collections; from phid_ros.io.parts import recording_parts; "
    "collections.deque(recording_parts(sys.argv[1]), maxlen=0)"
)
# peak memory of ada499f per hour of recording (this script's table of 2026-11-25; import: 373c035
# read a day's PMU export in 3.5 GB): what keeps the baseline out of a run that would not fit
BASELINE_GB_PER_HOUR = {
    "simulate": 2.45,
    "replay": 1.9,
    "identify": 1.25,
    "track": 1.9,
    "info": 0.75,
    "read": 0.75,
    "import": 0.15,
    "import-comtrade": 1.5,  # the comtrade package's reader: Python floats of every channel
    "validate": 1.0,  # a455582 read the recording whole (load_recording), then cut it
}
COMMANDS = ("read", "replay", "identify", "track", "info", "import", "import-comtrade", "validate")


def measured(cmd: list[str], cwd: Path) -> tuple[float, float, int]:
    """(wall s, peak RSS MB, exit status) of ``cmd`` in its own process."""
    out = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M", *cmd], capture_output=True, text=True, cwd=cwd)
    found = re.findall(r"TIME ([\d.]+) (\d+)", out.stderr)
    if not found:
        raise RuntimeError(f"{cmd}: no timing ({out.stderr[-300:]})")
    wall, kb = found[-1]
    return float(wall), int(kb) / 1024, out.returncode


# the PMU export's channel map: a P-class PMU at the terminals, speed and field voltage beside it
PMU_MAP = """machine: {mva: 1000, kv: 20, f_nominal_hz: 50, phasor_window_cycles: 2}
time: Timestamp
channels:
  v_t: {name: "GEN1:V1_MAG", unit: V}
  theta_t: {name: "GEN1:V1_ANG", unit: deg}
  i_t: {name: "GEN1:I1_MAG", unit: A}
  phi_i: {name: "GEN1:I1_ANG", unit: deg}
  omega: {name: SPEED, unit: pu}
  v_f: EFD
"""
PMU_EVERY = 20  # 1 kHz samples -> 50 reports per second, a PMU's rate on a 50 Hz system


def pmu_export(bag: Path, out: Path) -> Path:
    """The recording as a PMU's day-long CSV export (ISO stamps, phasors in V, A and degrees),
    written part by part: what ``phid import-pmu`` reads in the ``import`` row."""
    import numpy as np

    from phid_ros.io.parts import recording_parts
    from phid_ros.model.conventions import dq_to_terminal

    kv, mva = 20.0, 1000.0
    v_base, i_base = kv * 1e3 / np.sqrt(3), mva * 1e6 / (np.sqrt(3) * kv * 1e3)
    names = ["Timestamp", "GEN1:V1_MAG", "GEN1:V1_ANG", "GEN1:I1_MAG", "GEN1:I1_ANG", "SPEED", "EFD"]
    pending: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]] = {}  # per stream: what the others lack
    t0: int | None = None
    with out.open("w") as fh:
        fh.write(",".join(names) + "\n")
        for part in recording_parts(bag):
            # a part's streams end at different stamps: rows are written up to the earliest end
            for name, st in part.streams.items():
                t, ch = pending.get(name, (np.empty(0, np.int64), {}))
                pending[name] = (
                    np.concatenate([t, st.t_ns]),
                    {c: np.concatenate([ch.get(c, np.empty(0)), np.asarray(x)]) for c, x in st.channels.items()},
                )
            upto = min(int(t[-1]) for t, _ in pending.values())
            if t0 is None:
                t0 = int(pending["pt_ct"][0][0])
            m: dict[str, np.ndarray] = {}
            for name, (t, ch) in list(pending.items()):
                n = int(np.searchsorted(t, upto, side="right"))
                report = ((t[:n] - t0) // part.streams[name].period_ns) % PMU_EVERY == 0
                m.update({c: x[:n][report] for c, x in ch.items()})
                stamps_ns = t[:n][report]
                pending[name] = (t[n:], {c: x[n:] for c, x in ch.items()})
            i_mag, i_ang = dq_to_terminal(m["i_d"], m["i_q"], m["delta"])
            stamps = np.datetime_as_string(stamps_ns.astype("datetime64[ns]"), unit="us")
            cols = [
                m["v_t"] * v_base,
                np.degrees(np.angle(np.exp(1j * m["theta_t"]))),
                i_mag * i_base,
                np.degrees(np.angle(np.exp(1j * i_ang))),
                m["omega"],
                m["v_f"],
            ]
            rows = [",".join((t, *(f"{v:.9g}" for v in vals))) for t, *vals in zip(stamps.tolist(), *cols)]
            if rows:
                fh.write("\n".join(rows) + "\n")
    (out.parent / "pmu_map.yaml").write_text(PMU_MAP)
    return out


# the COMTRADE export's channel map: a disturbance recorder's waveforms, field voltage and speed
COMTRADE_MAP = """machine: {mva: 1000, kv: 20, f_nominal_hz: 50}
channels:
  v_a: VA
  v_b: VB
  v_c: VC
  i_a: IA
  i_b: IB
  i_c: IC
  omega: {name: SPEED, unit: pu}
  v_f: EFD
"""


def comtrade_export(bag: Path, out: Path) -> Path:
    """The recording as a continuous disturbance recorder's COMTRADE (C37.111-1999, 16-bit
    BINARY): the phase voltages and currents as waveforms at the bag's 1 kHz (20 samples a 50 Hz
    cycle), field voltage and speed, written part by part: what the ``import-comtrade`` row reads."""
    import numpy as np

    from phid_ros.io.parts import recording_parts
    from phid_ros.model.conventions import dq_to_terminal

    kv, mva, f0, fs = 20.0, 1000.0, 50.0, 1000.0
    v_base, i_base = kv * 1e3 / np.sqrt(3), mva * 1e6 / (np.sqrt(3) * kv * 1e3)
    # each channel's scale: 16 bits over 2 pu peak (the stored integer = value / a)
    scale = {"V": 2 * np.sqrt(2) * v_base / 32000, "I": 2 * np.sqrt(2) * i_base / 32000, "EFD": 4 / 32000}
    scale["SPEED"] = 2 / 32000
    names = ["VA", "VB", "VC", "IA", "IB", "IC", "EFD", "SPEED"]
    row = np.dtype([("n", "<u4"), ("t", "<u4"), ("a", "<i2", (len(names),))])
    n = 0
    with out.with_suffix(".dat").open("wb") as fh:
        for part in recording_parts(bag):
            st = {name: part.streams[name] for name in ("pt_ct", "pmu", "encoder", "excitation")}
            k = min(len(x.t_ns) for x in st.values())  # the streams share the 1 kHz grid
            c = {q: np.asarray(x)[:k] for s in st.values() for q, x in s.channels.items()}
            t = (np.arange(n, n + k)) / fs
            i_mag, i_ang = dq_to_terminal(c["i_d"], c["i_q"], c["delta"])
            phase = [2 * np.pi * (f0 * t - j / 3) for j in range(3)]
            v = [np.sqrt(2) * c["v_t"] * v_base * np.cos(ph + c["theta_t"]) for ph in phase]
            i = [np.sqrt(2) * i_mag * i_base * np.cos(ph + i_ang) for ph in phase]
            a = [*(x / scale["V"] for x in v), *(x / scale["I"] for x in i)]
            a += [c["v_f"] / scale["EFD"], c["omega"] / scale["SPEED"]]
            rec = np.zeros(k, dtype=row)
            rec["n"], rec["t"] = np.arange(n + 1, n + k + 1), np.round(t * 1e6).astype(np.int64) % (1 << 32)
            rec["a"] = np.column_stack([np.round(x) for x in a]).astype(np.int16)
            fh.write(rec.tobytes())
            n += k
    a_of = [scale["V"]] * 3 + [scale["I"]] * 3 + [scale["EFD"], scale["SPEED"]]
    units = ["V"] * 3 + ["A"] * 3 + ["pu", "pu"]
    lines = ["BENCH,RECORDER,1999", f"{len(names)},{len(names)}A,0D"]
    lines += [
        f"{j},{nm},,,{u},{a:.12g},0,0,-32767,32767,1,1,P" for j, (nm, u, a) in enumerate(zip(names, units, a_of), 1)
    ]
    start = "01/01/2026,00:00:00.000000"
    lines += [f"{f0:g}", "1", f"{fs:g},{n}", start, start, "BINARY", "1"]
    out.write_text("\r\n".join(lines) + "\r\n", newline="")
    (out.parent / "comtrade_map.yaml").write_text(COMTRADE_MAP)
    return out


def unit_record(out: Path) -> Path:
    """The simulated machine (TABLE 1, the ambient recording's) as a .dyr for ``phid validate``."""
    from phid_ros.export.formats import psse_dyr
    from phid_ros.export.record import build_record
    from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1

    doc = {"parameters": TABLE1.as_dict(), "identifiable": dict.fromkeys(PARAMETER_NAMES, True)}
    out.write_text(psse_dyr(build_record(doc, source="TABLE 1", mva=1000.0)))
    return out


def commands(bag: Path, work: Path, tag: str) -> dict[str, list[str]]:
    """Each command on ``bag`` as ``python -m phid_ros.cli.main``, run in the tree it is measured in."""
    phid = [sys.executable, "-m", "phid_ros.cli.main"]
    pmu = bag.with_suffix(".pmu.csv")
    return {
        "read": [sys.executable, "-c", READ, str(bag)],
        "import": [
            *phid,
            "import-pmu",
            str(pmu),
            "--map",
            str(pmu.parent / "pmu_map.yaml"),
            "--out",
            str(work / f"import_{tag}_{bag.stem}.mcap"),
        ],
        "import-comtrade": [
            *phid,
            "import-comtrade",
            str(bag.with_suffix(".cfg")),
            "--map",
            str(bag.parent / "comtrade_map.yaml"),
            "--out",
            str(work / f"comtrade_{tag}_{bag.stem}.mcap"),
        ],
        "replay": [*phid, "replay", str(bag), "--out", str(work / f"replay_{tag}_{bag.stem}.mcap"), "--force"],
        "identify": [*phid, "identify", str(bag)],
        "validate": [*phid, "validate", str(bag.parent / "unit.dyr"), str(bag)],
        "track": [*phid, "track", str(bag)],
        "info": [*phid, "info", str(bag)],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, nargs="+", default=[0.5, 2.0])
    ap.add_argument("--baseline", help="a git revision to measure beside this tree (e.g. ada499f)")
    ap.add_argument("--baseline-max-gb", type=float, default=16.0)
    ap.add_argument("--commands", nargs="+", choices=COMMANDS, default=list(COMMANDS))
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "out" / "long")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    trees = {"now": ROOT}
    tmp = None
    if args.baseline:
        tmp = tempfile.mkdtemp(prefix="phid-baseline-")
        subprocess.run(["git", "worktree", "add", "-q", "--detach", tmp, args.baseline], cwd=ROOT, check=True)
        trees["base"] = Path(tmp)
    try:
        print(f"{'recording':>9} {'command':<9} {'tree':<5} {'wall s':>8} {'peak MB':>8} {'x real':>8} {'exit':>4}")
        for hours in args.hours:
            seconds = int(hours * 3600)
            bag = args.out / f"ambient_{seconds}s.mcap"
            rows: list[tuple[str, str, float, float, int]] = []
            if not bag.exists():
                sim = [sys.executable, "-m", "phid_ros.cli.main", "simulate", "--ambient", str(seconds)]
                rows.append(("simulate", "now", *measured([*sim, "--out", str(bag)], ROOT)))
            if not bag.with_suffix(".pmu.csv").exists():
                pmu_export(bag, bag.with_suffix(".pmu.csv"))
            if not bag.with_suffix(".cfg").exists():
                comtrade_export(bag, bag.with_suffix(".cfg"))
            if not (bag.parent / "unit.dyr").exists():
                unit_record(bag.parent / "unit.dyr")
            for name in args.commands:
                for tag, tree in trees.items():
                    if tag == "base" and BASELINE_GB_PER_HOUR[name] * hours > args.baseline_max_gb:
                        print(
                            f"{hours:>8g}h {name:<9} {tag:<5} {'not run: needs ~':>18}"
                            f"{BASELINE_GB_PER_HOUR[name] * hours:.0f} GB"
                        )
                        continue
                    cmd = commands(bag, args.out, tag)[name]
                    if tag == "base" and name == "read":
                        cmd = [
                            sys.executable,
                            "-c",
                            "import sys; from phid_ros.io.bags import read_recording; read_recording(sys.argv[1])",
                            str(bag),
                        ]
                    if name.startswith("import"):  # an import never overwrites: the last run's bag goes first
                        Path(cmd[-1]).unlink(missing_ok=True)
                    rows.append((name, tag, *measured(cmd, tree)))
            by = {(n, t): (w, mb) for n, t, w, mb, _ in rows}
            for name, tag, wall, mb, code in rows:
                ratio = ""
                if tag == "now" and (name, "base") in by:
                    w0, mb0 = by[(name, "base")]
                    ratio = f"  vs base: {w0 / wall:.2f}x faster, {mb0 / mb:.1f}x less memory"
                head = f"{hours:>8g}h {name:<9} {tag:<5}"
                print(f"{head} {wall:>8.1f} {mb:>8.0f} {seconds / wall:>8.0f} {code:>4}{ratio}")
            sys.stdout.flush()
    finally:
        if tmp is not None:
            subprocess.run(["git", "worktree", "remove", "--force", tmp], cwd=ROOT, check=False)


if __name__ == "__main__":
    main()
