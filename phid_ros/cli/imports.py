"""``phid import-csv``, ``import-comtrade``, ``import-pmu``: field recordings -> one scenario set."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from rich.console import Console

from phid_ros.cli.common import warn, write_output
from phid_ros.cli.progress import ProgressLine
from phid_ros.errors import PhidError
from phid_ros.io.files.outputs import atomic_output, refuse_inputs
from phid_ros.io.recording import Recording


def import_csv_command(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.io.csvset.csv_import import import_csv_set

    out = Path(args.out)
    refuse_inputs([out], [args.manifest])
    if out.exists():
        raise PhidError(f"{out}: already exists, not overwriting")
    with ProgressLine(f"importing {args.manifest}") as progress:
        rec, warnings = import_csv_set(args.manifest, strict=args.strict)
        progress.update(f"writing {out}")
        with atomic_output(out) as tmp:
            write_recording(tmp, rec, block_size=args.block_size)
    for w in warnings:
        warn(w)
    console.print(f"wrote {out} ({len(rec.scenarios)} scenarios)")
    return 0


def import_comtrade_command(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.field.comtrade_import import import_comtrade

    return _import_field(args, console, import_comtrade)


def import_pmu_command(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.field.pmu_csv import import_pmu_csv

    return _import_field(args, console, import_pmu_csv)


def _import_field(args: argparse.Namespace, console: Console, read: Callable[..., Recording]) -> int:
    """Field recordings through a channel map -> one scenario set, written as ``phid simulate`` writes."""
    from phid_ros.io.field.channel_map import load_channel_map

    out = Path(args.out)
    if out.name == "manifest.json":  # a CSV scenario set: its folder is the output
        out.parent.mkdir(parents=True, exist_ok=True)
    refuse_inputs([out], [*args.recordings, *args.map])
    if out.exists():
        raise PhidError(f"{out}: already exists, not overwriting")
    dup = sorted({m for m in args.map if args.map.count(m) > 1})
    if dup:
        raise PhidError(f"--map {dup[0]} given twice")
    maps = [load_channel_map(m) for m in args.map]
    with ProgressLine(f"importing {len(args.recordings)} recording(s)") as progress:
        rec = read(args.recordings, maps)
        progress.update(f"writing {out}")
        write_output(out, rec, args.block_size)
    for w in rec.warnings:  # what the import did: resampled clocks, the field base it calibrated
        warn(w)
    console.print(f"wrote {out} ({len(rec.scenarios)} scenarios)")
    return 0
