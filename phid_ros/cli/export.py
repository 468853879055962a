"""``phid export``: an identification result (and its diagnosis) as a planning-model record."""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console

from phid_ros.cli.common import warn
from phid_ros.cli.tables import Col, print_table
from phid_ros.export.formats import PSLF_CONTROLS, WRITERS, pslf_left_out
from phid_ros.export.record import FIELDS, ExportError, build_record
from phid_ros.io.files.outputs import refuse_inputs, write_text
from phid_ros.io.files.results import read_json

SUFFIX = {"psse-dyr": ".dyr", "pslf-dyd": ".dyd", "andes": ".andes.json"}


def export_command(args: argparse.Namespace, console: Console) -> int:
    result = read_json(args.result)
    diagnosis = read_json(args.diagnosis) if args.diagnosis else None
    mva = args.mva if args.mva is not None else result.get("base_mva")
    if mva is None:
        raise ExportError(f"{args.result}: the result does not say the machine's MVA base; give it with --mva")
    out = Path(args.out) if args.out else Path(args.result).with_suffix(SUFFIX[args.format])
    refuse_inputs([out], [args.result, args.diagnosis, args.base])
    existing = None
    bus, machine_id = args.bus or 1, args.id or "1"
    if args.base:
        from phid_ros.export.dyr_read import read_unit

        existing = read_unit(args.base, args.bus, args.id)
        # the record goes where the unit's record is: a base at bus 5 was written at bus 1, unsaid
        bus, machine_id = args.bus or existing.bus, args.id or existing.machine_id
    rec = build_record(
        result,
        source=str(args.result),
        model=args.model,
        mva=float(mva),
        kv=args.kv,
        bus=bus,
        machine_id=machine_id,
        diagnosis=diagnosis,
        diagnosis_source=str(args.diagnosis or ""),
        allow_flagged=args.allow_flagged,
        existing=existing,
    )
    if args.f_nominal is not None:
        rec.f_nominal_hz = args.f_nominal
    if rec.flagged:
        warn(f"writing parameters that are NOT identified (--allow-flagged): {', '.join(rec.flagged)}")
    if rec.kept:
        warn(f"kept from {rec.kept_from} (the recordings did not determine them): {', '.join(rec.kept)}")
    for w in rec.warnings:
        warn(w)
    if existing is not None and existing.carried and args.format != "psse-dyr":
        warn(
            f"{args.base}: {', '.join(r.model for r in existing.carried)} (records phid does not model) not written "
            f"to a {args.format} file, which has no layout for them here; the .dyr carries them as written"
        )
    written = dict(rec.values)
    sources: dict[str, str] = dict(rec.sources)
    if args.format == "psse-dyr":
        written["D"] = rec.torque_form_damping()
        if rec.p_m0 is None:
            warn(
                f"{args.result}: no operating point (identified before phid 0.3): D is written as identified, "
                "but PSS/E divides P_m by the speed and needs D - P_m0; identify again to have it converted"
            )
        else:
            sources["D"] += f", minus P_m0 = {rec.p_m0:.3g} (PSS/E's torque form)"
    left_out = pslf_left_out(rec) if args.format == "pslf-dyd" else []
    if left_out:
        warn(
            f"{args.result}: the {', '.join(left_out)} record(s) are not written to a .dyd (PSLF's layout for "
            f"them is not checked here; it is for {', '.join(PSLF_CONTROLS)}); the .dyr and ANDES formats carry them"
        )
    write_text(out, WRITERS[args.format](rec))
    rows = [[f, FIELDS[f].split(",")[0].split(" (")[0], f"{written[f]:.6g}", sources[f]] for f in rec.fields]
    cols = [
        Col("field", justify="left", key=True),
        Col("symbol", justify="left", keep=3),
        Col("value"),
        Col("source", justify="left", keep=8, text=True),
    ]
    print_table(console, f"{rec.model} record, bus {rec.bus} id {rec.machine_id}, {rec.mva:g} MVA base", cols, rows)
    beside = [c.model for c in rec.controls if c.model not in left_out]
    console.print(f"wrote {out} ({args.format}{''.join(', with ' + m for m in beside)})", highlight=False)
    return 0
