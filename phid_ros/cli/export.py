"""``phid export``: an identification result (and its diagnosis) as a planning-model record."""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console

from phid_ros.api import export_record
from phid_ros.cli.common import warn
from phid_ros.cli.tables import Col, print_table
from phid_ros.export.record import FIELDS
from phid_ros.io.files.outputs import refuse_inputs, write_text

SUFFIX = {"psse-dyr": ".dyr", "pslf-dyd": ".dyd", "andes": ".andes.json"}


def export_command(args: argparse.Namespace, console: Console) -> int:
    out = Path(args.out) if args.out else Path(args.result).with_suffix(SUFFIX[args.format])
    refuse_inputs([out], [args.result, args.diagnosis, args.base])
    done = export_record(
        args.result,
        args.format,
        model=args.model,
        mva=args.mva,
        kv=args.kv,
        bus=args.bus,
        machine_id=args.id,
        diagnosis_path=args.diagnosis,
        base=args.base,
        allow_flagged=args.allow_flagged,
        f_nominal_hz=args.f_nominal,
    )
    for w in done.warnings:
        warn(w)
    write_text(out, done.text)
    rec = done.record
    rows = [[f, FIELDS[f].split(",")[0].split(" (")[0], f"{done.written[f]:.6g}", done.sources[f]] for f in rec.fields]
    cols = [
        Col("field", justify="left", key=True),
        Col("symbol", justify="left", keep=3),
        Col("value"),
        Col("source", justify="left", keep=8, text=True),
    ]
    print_table(console, f"{rec.model} record, bus {rec.bus} id {rec.machine_id}, {rec.mva:g} MVA base", cols, rows)
    beside = [c.model for c in rec.controls if c.model not in done.left_out]
    console.print(f"wrote {out} ({args.format}{''.join(', with ' + m for m in beside)})", highlight=False)
    return 0
