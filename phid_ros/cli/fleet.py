"""``phid fleet`` and ``phid history``: the batch side, and what it learned about each unit."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from phid_ros.cli.common import warn
from phid_ros.cli.history_report import verdict_rows
from phid_ros.cli.tables import CONCISE_LEGEND, Col, estimate_text, print_table
from phid_ros.errors import PhidError
from phid_ros.fleet.history import (
    SISTER_SIGMAS,
    Change,
    History,
    Row,
    changes,
    designs_of,
    iter_units,
    sister_gaps,
)
from phid_ros.fleet.run import HISTORY_FILE, FleetOptions, run_fleet
from phid_ros.model.conventions import utc_of_stamp
from phid_ros.model.parameters import PARAMETER_NAMES, SYMBOLS


def fleet_command(args: Any, console: Console) -> int:
    if args.workers < 0:
        raise PhidError(f"--workers {args.workers}: give 0 (one per core) or a positive number of processes")
    if args.scheduler and args.workers:
        raise PhidError("--workers sizes the local cluster; an existing cluster (--scheduler) has its own workers")
    options = FleetOptions(args.scheduler, args.workers, args.diagnose, args.retry_failed)
    t0 = time.perf_counter()
    # on a terminal a live bar (rich) above the per-recording lines; in a log file the lines alone
    progress = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )
    bar = progress.add_task("checking the history", total=None)

    def on_hashing(k: int, n: int) -> None:
        progress.update(bar, description="checking the history", completed=k, total=n)

    def on_cluster(client: Any) -> None:
        from phid_ros.cluster import describe

        info = describe(client)
        where = "local cluster" if info.local else "cluster"
        dash = f", dashboard {info.dashboard}" if info.dashboard else ", no dashboard (bokeh not installed)"
        console.print(f"{where} {info.scheduler}: {info.workers} worker(s){dash}", highlight=False)
        progress.update(bar, description="recordings", completed=0, total=None)

    def on_row(row: Row, done: int, total: int) -> None:
        what = "ok" if row.status == "ok" else f"FAILED: {row.error}"
        console.print(
            f"[{done}/{total}] {row.unit} {Path(row.recording).name}: {what} ({row.wall_s:.1f} s)",
            highlight=False,
            soft_wrap=True,
        )
        progress.update(bar, description="recordings", completed=done, total=total)

    if not console.is_terminal:
        console.print("checking the inventory against the history", highlight=False)
    with progress:
        result = run_fleet(
            args.inventory, args.out, options, on_cluster=on_cluster, on_row=on_row, on_hashing=on_hashing
        )
    for w in result.warnings:
        warn(w)
    console.print(
        f"{result.recordings} recording(s): {result.skipped} already in the history, {result.submitted} run"
        + (f" ({result.redone} identified by an older method, so again)" if result.redone else "")
        + ", "
        f"{result.failed} failed; {time.perf_counter() - t0:.1f} s; history {Path(args.out) / HISTORY_FILE}",
        highlight=False,
    )
    if args.summary:
        with History(Path(args.out) / HISTORY_FILE, create=False) as h:
            print_summary(console, h.rows())
    return 0


def _iso(ns: int | None) -> str:
    if ns is None:
        return "—"
    return utc_of_stamp(ns).strftime("%Y-%m-%d %H:%M")


def _value(row: Row, name: str) -> str:
    return estimate_text(row.values.get(name, math.nan), row.stds.get(name, math.nan), bool(row.identifiable.get(name)))


def print_summary(console: Console, rows: list[Row]) -> None:
    """One row per unit: its latest identified set, how many recordings, and what is flagged."""
    cols = [Col("unit", "left", key=True), Col("latest", "left"), Col("sets"), Col("fail")]
    cols += [Col(SYMBOLS[n]) for n in PARAMETER_NAMES] + [Col("flags", "left", text=True)]
    table = []
    for unit, unit_rows in iter_units(rows):
        good = [r for r in unit_rows if r.status == "ok"]
        failed = len(unit_rows) - len(good)
        flags = [f"{SYMBOLS[c.parameter]} {c.relative:+.1%} ({c.sigmas:.0f}σ)" for c in changes(unit_rows)]
        if failed:
            flags.append(f"{failed} failed")
        latest = good[-1] if good else None
        if latest and latest.verdicts:
            bad = sum(not v["passed"] for v in latest.verdicts)
            flags.append(f"record on file: {bad} of {len(latest.verdicts)} events fail")
        effects = ", ".join(e["name"] for e in latest.effects) if latest and latest.effects else ""
        table.append(
            [unit, _iso(latest.start_ns)[:10] if latest else "—", str(len(good)), str(failed)]
            + [_value(latest, n) if latest else "—" for n in PARAMETER_NAMES]
            + ["; ".join(flags + ([effects] if effects else [])) or "—"]
        )
    print_table(console, "fleet: latest identified set per unit", cols, table, CONCISE_LEGEND)
    print_sisters(console, rows)


def print_sisters(console: Console, rows: list[Row], unit: str | None = None) -> None:
    """Each design's units compared (those of ``unit``'s design only, when given)."""
    gaps = sister_gaps(rows)
    for design, units in designs_of(rows).items():
        if unit is not None and unit not in units:
            continue
        mine = [g for g in gaps if g.design == design and unit in (None, g.first.unit, g.second.unit)]
        head = f"sister units of design {design} ({', '.join(units)})"
        if not mine:
            console.print(
                f"{head}: agree within {SISTER_SIGMAS:g} σ on every parameter both identified", highlight=False
            )
            continue
        console.print(f"{head} disagree beyond {SISTER_SIGMAS:g} σ:", highlight=False)
        for g in mine:
            console.print(f"  {g.text()}", highlight=False, soft_wrap=True)


def print_verdicts(console: Console, unit: str, rows: list[Row]) -> None:
    records = sorted({r.record for r in rows if r.record})
    if not records:
        return
    table = verdict_rows(rows)
    if not table:
        console.print(f"record on file {', '.join(records)}: no event it could be played against", highlight=False)
        return
    cols = [
        Col("event (UTC)", "left", key=True),
        Col("event", "left", breakable=True),
        Col("checks passed", "left"),
        Col("worst check", "left"),
        Col("err / band"),
        Col("", "left"),
    ]
    failed = sum(row[-1] == "FAIL" for row in table)
    print_table(
        console,
        f"unit {unit}: the record on file at each event ({Path(records[-1]).name})",
        cols,
        table,
        f"played in as phid validate plays it; {failed} of {len(table)} events failed a check",
    )


def print_history(console: Console, unit: str, rows: list[Row], flagged: list[Change]) -> None:
    cols = [Col("recorded (UTC)", "left", key=True)] + [Col(SYMBOLS[n]) for n in PARAMETER_NAMES]
    cols.append(Col("recording / error", "left", text=True))
    marks = {(id(c.after), c.parameter) for c in flagged}
    table = []
    for r in rows:
        cells = [
            (_value(r, n) + ("!" if (id(r), n) in marks else "")) if r.status == "ok" else "" for n in PARAMETER_NAMES
        ]
        effects = ", ".join(e["name"] for e in r.effects)
        note = (
            f"FAILED {r.error}"
            if r.status == "failed"
            else Path(r.recording).name + (f" ({effects})" if effects else "")
        )
        table.append([_iso(r.start_ns), *cells, note])
    print_table(console, f"unit {unit}: parameter history", cols, table, CONCISE_LEGEND + "; ! = flagged change")


def history_command(args: Any, console: Console) -> int:
    from phid_ros.io.files.outputs import refuse_inputs

    path = Path(args.fleet) / HISTORY_FILE
    refuse_inputs([args.report], [path])
    with History(path, create=False) as h:
        rows = h.rows(args.unit)
        if not rows:
            known = ", ".join(h.units()) or "none"
            raise PhidError(f"{path}: no recordings of unit {args.unit!r} (units in this history: {known})")
        everyone = h.rows()
    flagged = changes(rows, args.sigmas)
    print_history(console, args.unit, rows, flagged)
    print_verdicts(console, args.unit, rows)
    print_sisters(console, everyone, args.unit)
    for c in flagged:
        console.print(
            f"{SYMBOLS[c.parameter]} changed {c.relative:+.2%} ({c.sigmas:.1f} σ) between "
            f"{_iso(c.before.start_ns)} and {_iso(c.after.start_ns)}",
            highlight=False,
        )
    if not flagged:
        console.print(f"no change beyond {args.sigmas:g} σ between consecutive well-identified sets", highlight=False)
    if args.report:
        from phid_ros.cli.history_report import write_report

        write_report(args.report, args.unit, rows, flagged, sister_gaps(everyone))
        console.print(f"wrote {args.report}", highlight=False)
    return 0
