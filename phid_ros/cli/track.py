"""``phid track``: the sliding-window tracker over a recording, hop by hop."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from phid_ros.cli.common import load_parameters, warn
from phid_ros.cli.monitor_report import HealthLog
from phid_ros.cli.progress import ProgressLine
from phid_ros.cli.tables import CONCISE_LEGEND, estimate_text
from phid_ros.errors import PhidError
from phid_ros.io.recording import Recording
from phid_ros.model.conventions import NS
from phid_ros.model.parameters import SYMBOLS, TABLE1, GeneratorParameters
from phid_ros.stream.levels import Level
from phid_ros.stream.tracker import TRACKED, TrackPoint


def health_over_time(rec: Any, bin_s: float) -> HealthLog:
    """Each stream's completeness per ``bin_s`` of the recording, from its stamps.

    Level per bin: OK with 99 % of the expected samples, WARN with 90 %, ERROR below,
    STALE with none; the counters are the samples missing, the gaps and the backward
    stamps since the start.
    """
    tally = HealthTally(bin_s)
    tally.add(rec)
    return tally.log()


class HealthTally:
    """:func:`health_over_time` gathered part by part (a day's recording is never held whole):
    per stream and bin, the samples, gaps and backward stamps counted; a step between two parts
    counted as within one."""

    def __init__(self, bin_s: float) -> None:
        self.bin_ns = int(bin_s * NS)
        self.start: int | None = None
        self.end: int | None = None
        self._streams: dict[str, dict[str, Any]] = {}

    def add(self, rec: Any) -> None:
        import numpy as np

        firsts = [int(s.t_ns[0]) for s in rec.streams.values() if len(s)]
        if not firsts:
            return
        if self.start is None:
            self.start = min(firsts)
        self.end = max([self.end or self.start, *(int(s.t_ns.max()) for s in rec.streams.values() if len(s))])
        for name, s in rec.streams.items():
            if not len(s):
                continue
            st = self._streams.setdefault(name, {"period": s.period_ns, "last": None})
            t = s.t_ns
            if st["last"] is None:
                step, after = np.diff(t), t[1:]
            else:
                step, after = np.diff(t, prepend=st["last"]), t
            st["last"] = int(t[-1])
            for key, at in (("got", t), ("gaps", after[step > 1.5 * s.period_ns]), ("jumps", after[step <= 0])):
                idx = (at[at >= self.start] - self.start) // self.bin_ns
                counts = np.bincount(idx, minlength=0)
                have = st.get(key, np.zeros(0, np.int64))
                if len(counts) > len(have):
                    have = np.concatenate((have, np.zeros(len(counts) - len(have), np.int64)))
                have[: len(counts)] += counts
                st[key] = have

    def log(self) -> HealthLog:
        import numpy as np

        if self.start is None or self.end is None:
            return HealthLog(t_s=[])
        start, end = self.start, self.end
        edges = np.arange(start, end + self.bin_ns, self.bin_ns)
        n = len(edges) - 1
        log = HealthLog(t_s=[float(t) for t in (edges[1:] - start) / NS])

        def binned(st: dict[str, Any], key: str) -> Any:
            x = np.zeros(n, np.int64)
            have = st.get(key, np.zeros(0, np.int64))
            x[: min(n, len(have))] = have[:n]
            x[-1] += have[n:].sum()  # a stamp on the last edge is in the last bin, as np.histogram puts it
            return x

        for name, st in self._streams.items():
            got = binned(st, "got")
            # the last bin may be cut by the end of the recording: expect only what it spans
            expected = (np.minimum(edges[1:], end + st["period"]) - edges[:-1]) / st["period"]
            share = got / expected
            missing = np.cumsum(np.maximum(0, np.round(expected) - got)).astype(int)
            gaps = np.cumsum(binned(st, "gaps"))
            jumps = np.cumsum(binned(st, "jumps"))
            levels = np.where(
                share >= 0.99,
                Level.OK,
                np.where(share >= 0.9, Level.WARN, np.where(share > 0, Level.ERROR, Level.STALE)),
            )
            log.streams[name] = [
                (Level(lv), int(m), int(g), int(j)) for lv, m, g, j in zip(levels, missing, gaps, jumps)
            ]
        return log


def hop_line(start_ns: int, p: TrackPoint) -> str:
    """One hop on one line of at most 80 columns: the window's end, then the six tracked values."""
    cells = []
    for n in TRACKED:
        e = p.estimates.get(n)
        cells.append(f"{estimate_text(e.value, e.std, e.identifiable) if e else '—':>11}")
    return f"{(p.t_ns - start_ns) / NS:>7.0f} " + " ".join(cells)


def base_parameters(args: Any) -> GeneratorParameters:
    if not args.base:
        warn(
            f"no --base: X_d and X_q are the paper's Table 1 values ({TABLE1.X_d:g}, {TABLE1.X_q:g} pu), "
            "not this machine's; "
            "give --base PARAMS.json (phid identify --json) for real data"
        )
        return TABLE1
    return load_parameters(args.base)


def track_command(args: Any, console: Any) -> int:
    if args.hop > args.window:
        raise PhidError(f"--hop {args.hop:g} s is longer than --window {args.window:g} s: samples would be skipped")
    from phid_ros.api import track_file
    from phid_ros.io.files.outputs import refuse_inputs

    refuse_inputs([args.out, args.report], [args.bag, args.base])
    if args.out:
        if Path(args.out).exists():
            raise PhidError(f"{args.out}: already exists, not overwriting")
    base = base_parameters(args)  # checked before the recording is read
    health = HealthTally(args.hop)
    first: list[int] = []

    def show(p: TrackPoint, read: float) -> None:
        start = first[0] if first else p.t_ns
        progress.print_above(console, hop_line(start, p), highlight=False)
        for a in p.alarms:
            progress.print_above(console, f"{'':>8}alarm: {a}", style="bold red", highlight=False, markup=False)
        progress.update(f"tracking: {(p.t_ns - start) / NS:.0f} s, {100 * read:.0f} % of the file")

    def tally(part: Recording) -> None:
        if not first:  # the recording read: its table's head (an unreadable file says only why)
            first.append(min(int(s.t_ns[0]) for s in part.streams.values() if len(s)))
            say = progress.print_above
            say(console, f"sliding-window tracking ({args.window:g} s window, {args.hop:g} s hop)", highlight=False)
            say(console, CONCISE_LEGEND, style="dim", highlight=False)
            say(console, f"{'t s':>7} " + " ".join(f"{SYMBOLS[n]:>11}" for n in TRACKED), highlight=False)
        health.add(part)

    with ProgressLine("tracking: the first window") as progress:
        run = track_file(args.bag, base, args.window, args.hop, out=args.out, on_point=show, on_part=tally)
    for w in run.warnings:
        warn(w)
    points = run.points
    if not points:
        raise PhidError(f"{args.bag}: shorter than one tracking window ({args.window:g} s)")
    alarmed = sorted({n for p in points for n in p.alarmed})
    console.print(
        f"{len(points)} hops; alarms raised for: {', '.join(SYMBOLS[n] for n in alarmed) or 'none'}; "
        f"tracked in {run.wall_s:.1f} s (wall time)",
        highlight=False,
    )
    if args.report:
        from phid_ros.cli.monitor_report import write_track_report

        notes = [] if args.base else ["X_d and X_q: the paper's Table 1 values (no --base given)"]
        notes += sorted({q for p in points for q in p.problems})
        with ProgressLine(f"writing {args.report}"):
            write_track_report(
                args.report,
                run.overview,
                points,
                health.log(),
                str(args.bag),
                notes,
                f"{args.window:g} s window, {args.hop:g} s hop, {len(points)} hops",
            )
        console.print(f"wrote {args.report}", highlight=False)
    if args.out:
        console.print(f"wrote {len(points)} messages to {args.out}", highlight=False)
    return 0
