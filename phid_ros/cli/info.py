"""``phid info``: what is in a recording: per-stream samples, rates, spans, gaps and stamp problems,
its scenarios and events, and what its channels determine."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from phid_ros.cli.common import warn
from phid_ros.cli.tables import Col, print_table
from phid_ros.errors import PhidError
from phid_ros.io.recording import Recording
from phid_ros.model.conventions import NS, utc_of_stamp


@dataclass(frozen=True)
class StreamSummary:
    name: str
    samples: int
    rate_hz: float
    start_ns: int
    end_ns: int
    gaps: int
    gap_seconds: float
    backwards: int  # stamps not after their predecessor (duplicates, out of order, clock jumps)


class StreamTally:
    """Per-stream samples, rates, spans and gaps of a recording read in parts (``phid info`` on a day's bag):
    counts carried from part to part, a gap or a step back between two parts counted too; and
    which channels carry data, for the table of what they determine."""

    def __init__(self) -> None:
        self._streams: dict[str, dict[str, int]] = {}
        self.recorded: set[str] = set()
        self._theta = (np.inf, -np.inf)
        self.no_load = False
        self.loaded = False

    def add(self, rec: Recording) -> None:
        for name, s in rec.streams.items():
            if not len(s):
                continue
            st = self._streams.get(name)
            if st is None:
                st = self._streams[name] = {"period": s.period_ns, "samples": 0, "start": int(s.t_ns[0]), "last": 0}
                st.update(gaps=0, gap_ns=0, backwards=0)
                d = np.diff(s.t_ns)
            else:
                d = np.diff(s.t_ns, prepend=st["last"])
            gap = d > 1.5 * st["period"]
            st["samples"] += len(s)
            st["gaps"] += int(gap.sum())
            st["gap_ns"] += int((d[gap] - st["period"]).sum())
            st["backwards"] += int((d <= 0).sum())
            st["last"] = int(s.t_ns[-1])
            for c, x in s.channels.items():
                if c not in self.recorded and np.isfinite(x).any():
                    self.recorded.add(c)
        cols = {c: x for s in rec.streams.values() for c, x in s.channels.items()}
        if "theta_t" in cols and np.isfinite(cols["theta_t"]).any():
            self._theta = (
                min(self._theta[0], float(np.nanmin(cols["theta_t"]))),
                max(self._theta[1], float(np.nanmax(cols["theta_t"]))),
            )
        if "p_e" in cols and "q_e" in cols:
            current = np.hypot(cols["p_e"], cols["q_e"])
            self.no_load |= bool((current < 0.02).any())
            self.loaded |= bool((current >= 0.02).any())

    @property
    def measured(self) -> set[str]:
        """The channels with data; an angle that is 0 throughout is a recording's reference, not a measurement."""
        out = set(self.recorded)
        if not self._theta[1] > self._theta[0]:
            out.discard("theta_t")
        return out

    def summaries(self) -> list[StreamSummary]:
        return [
            StreamSummary(
                name=name,
                samples=st["samples"],
                rate_hz=NS / st["period"],
                start_ns=st["start"],
                end_ns=st["last"],
                gaps=st["gaps"],
                gap_seconds=st["gap_ns"] / NS,
                backwards=st["backwards"],
            )
            for name, st in self._streams.items()
        ]


def _iso(ns: int) -> str:
    return utc_of_stamp(ns).isoformat(timespec="milliseconds")


def info_command(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.bags.recordings import topic_table, walked_topic_table
    from phid_ros.io.parts import recording_parts
    from phid_ros.io.recording import expected_type

    path = Path(args.bag)
    if path.suffix == ".json":  # a CSV scenario set: no topics, the same streams and scenarios
        from phid_ros.api import load_recording

        rec = load_recording(path)
        for w in rec.warnings:
            warn(w)
        tally = StreamTally()
        tally.add(rec)
        console.print(f"{path} (a CSV scenario set, {len(rec.scenarios)} scenarios)", highlight=False)
        _print_recording(console, tally, rec.scenarios, rec.metadata)
        return 0
    try:
        topics = topic_table(path)
    except PhidError as index_error:
        # a file cut short has no index at its end: walk what is there and say how much it was
        if not path.exists():
            raise
        try:
            topics, cut = walked_topic_table(path)
        except (PhidError, OSError):
            raise index_error from None
        if not cut:
            raise
        if not topics:  # cut before the first whole message: nothing to show
            raise PhidError(cut[0]) from None
        for w in cut:
            warn(w)
    if not any(expected_type(t) for t, _, _ in topics):
        # an output bag (phid replay) or foreign data: the topic table is all there is to show
        table = Table(title=f"{path} (no sensor streams)", title_justify="left")
        for col in ("topic", "type", "messages"):
            table.add_column(col, justify="right" if col == "messages" else "left")
        for topic, msgtype, count in topics:
            table.add_row(topic, msgtype, str(count))
        console.print(table)
        return 0
    # read part by part: a day's bag is summed up in the memory of one part
    tally = StreamTally()
    parts = recording_parts(path)
    scenarios = []
    for part in parts:
        tally.add(part)
        scenarios += part.scenarios
    metadata = parts.metadata  # the reader's own warnings were said above, with the topic table
    table = Table(title=f"{path}", title_justify="left")
    for col in ("topic", "type", "messages"):
        table.add_column(col, justify="right" if col == "messages" else "left")
    for topic, msgtype, count in topics:
        table.add_row(topic, msgtype, str(count))
    console.print(table)
    _print_recording(console, tally, scenarios, metadata)
    if any(not sc.event_ns for sc in scenarios):
        _print_events(console, path, min(s.start_ns for s in tally.summaries()))
    return 0


def _print_events(console: Console, path: Path, t0: int) -> None:
    """The events of test files imported whole (markers without an event stamp), as ``phid
    identify`` cuts them: one per step, return or de-excitation, and what is left out."""
    from phid_ros.api import cut_scenarios

    cut = cut_scenarios(path)
    cols = (Col("scenario", "left", key=True, breakable=True), Col("kind", "left"), Col("event s"), Col("window s"))
    rows = [
        (sc.name, sc.kind, f"{(sc.start_ns - t0) / NS + sc.k_event * sc.dt:.3f}", f"{sc.n * sc.dt:.1f}")
        for sc in cut.scenarios
    ]
    print_table(console, "events (as phid identify cuts the scenarios)", cols, rows)
    for p in cut.problems:
        if "skipped" in p:
            console.print(f"left out: {p}", highlight=False)


def _print_recording(console: Console, tally: StreamTally, scenarios: list, metadata: dict[str, str]) -> None:
    """The streams, the scenarios, what the channels determine and the metadata of a recording."""
    streams = Table(title="sensor streams", title_justify="left")
    for col in ("stream", "samples", "rate Hz", "start (UTC)", "span s", "gaps", "gap s", "backwards"):
        streams.add_column(col, justify="left" if col in ("stream", "start (UTC)") else "right")
    for s in tally.summaries():
        streams.add_row(
            s.name,
            str(s.samples),
            f"{s.rate_hz:g}",
            _iso(s.start_ns),
            f"{(s.end_ns - s.start_ns) / NS:.3f}",
            str(s.gaps),
            f"{s.gap_seconds:.3f}",
            str(s.backwards),
        )
    console.print(streams)
    if scenarios:
        t0 = min(s.start_ns for s in tally.summaries())
        cols = (
            Col("name", "left", key=True, breakable=True),
            Col("kind", "left"),
            Col("role", "left", keep=5),
            Col("damping", "left", keep=4),
            Col("regulator", "left", keep=3),
            Col("event s"),
            Col("window s"),
        )
        rows = [
            (
                sc.name,
                sc.kind,
                sc.role,
                "yes" if sc.generator_damping else "no",
                sc.regulator,
                f"{(sc.event_ns - t0) / NS:.3f}" if sc.event_ns else "?",
                f"{(sc.end_ns - sc.start_ns) / NS:.1f}",
            )
            for sc in scenarios
        ]
        print_table(console, "scenarios", cols, rows)
    _print_determinable(console, tally)
    if metadata:
        console.print("metadata: " + ", ".join(f"{k}={v}" for k, v in sorted(metadata.items())), highlight=False)


def _print_determinable(console: Console, tally: StreamTally) -> None:
    """Channels recorded -> parameters determinable, for a recording that lacks some channels."""
    from phid_ros.cli.tables import print_determinable
    from phid_ros.ident.determinable import plan_for_channels
    from phid_ros.model.channels import CHANNELS

    recorded = tally.measured
    if recorded >= set(CHANNELS):
        return
    planned = plan_for_channels(recorded, {}, no_load=tally.no_load, loaded=tally.loaded)
    missing = ", ".join(c for c in CHANNELS if c not in recorded)
    print_determinable(console, f"what these channels determine (not recorded: {missing})", planned)
