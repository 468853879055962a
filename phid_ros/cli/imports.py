"""``phid import-csv``, ``import-comtrade``, ``import-pmu``: field recordings -> one scenario set."""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console

from phid_ros.api import write_output
from phid_ros.cli.common import warn
from phid_ros.cli.progress import ProgressLine
from phid_ros.errors import PhidError
from phid_ros.io.files.outputs import refuse_inputs


def import_csv_command(args: argparse.Namespace, console: Console) -> int:
    return _import(args, console, "csv", [args.manifest], [])


def import_comtrade_command(args: argparse.Namespace, console: Console) -> int:
    return _import(args, console, "comtrade", args.recordings, args.map)


def import_pmu_command(args: argparse.Namespace, console: Console) -> int:
    return _import(args, console, "pmu", args.recordings, args.map)


def _import(args: argparse.Namespace, console: Console, kind: str, paths: list, maps: list) -> int:
    """Recordings -> one scenario set (:func:`phid_ros.api.import_recordings`), written as
    ``phid simulate`` writes (a bag, an .mcap, or a CSV set's ``DIR/manifest.json``)."""
    from phid_ros.api import import_recordings

    out = Path(args.out)
    if out.name == "manifest.json" and kind != "csv":  # a CSV scenario set: its folder is the output
        out.parent.mkdir(parents=True, exist_ok=True)
    refuse_inputs([out], [*paths, *maps])
    if out.exists():
        raise PhidError(f"{out}: already exists, not overwriting")
    what = f"importing {paths[0]}" if kind == "csv" else f"importing {len(paths)} recording(s)"
    with ProgressLine(what) as progress:
        rec = import_recordings(paths, maps, kind=kind, strict=getattr(args, "strict", False))
        progress.update(f"writing {out}")
        write_output(out, rec, args.block_size)
    for w in rec.warnings:  # what the import did: resampled clocks, the field base it calibrated, ignored columns
        warn(w)
    console.print(f"wrote {out} ({len(rec.scenarios)} scenarios)")
    return 0
