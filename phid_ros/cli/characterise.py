"""``phid characterise``: a machine's open- and short-circuit curves -> IEEE 115's characteristics."""

from __future__ import annotations

import argparse
import math

from rich.console import Console

from phid_ros.cli.tables import Col, fmt, print_table


def characterise_command(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.api import characterise_sheet, result_provenance
    from phid_ros.io.files.outputs import refuse_inputs
    from phid_ros.io.files.results import write_json

    refuse_inputs([args.json], [args.sheet])
    sheet, c = characterise_sheet(args.sheet)
    refuse_inputs([args.json], [sheet.occ.source, sheet.scc.source])  # the curves the sheet names are inputs too
    rows = [
        ("I_fg", "A", c.i_fg, "field current for rated voltage on the air-gap line (the field's base)"),
        ("I_fsi", "A", c.i_fsi, "field current for rated armature current, short circuit"),
        ("X_du", "pu", c.x_du, "unsaturated synchronous reactance, I_fsi / I_fg"),
        ("X_d(rated V)", "pu", c.x_d_rated, f"1/SCR (SCR {c.scr:.3f}): I_fsi / I_f on the OCC at rated voltage"),
        ("S(1.0)", "", c.s10, "the measured OCC over the air-gap line, at 1.0 pu"),
        ("S(1.2)", "", c.s12, "likewise at 1.2 pu"),
    ]
    cols = (
        Col("quantity", "left", key=True),
        Col("unit", "left"),
        Col("value"),
        Col("± std", keep=5),
        Col("what", "left", keep=3, text=True),
    )
    print_table(
        console,
        f"IEEE 115 characteristics ({sheet.path})",
        cols,
        [(name, unit, fmt(e.value), fmt(e.std, 2), what) for name, unit, e, what in rows],
    )
    if math.isfinite(c.planning_worst):
        console.print(
            f"the planning models' quadratic curve through S(1.0), S(1.2) is within {100 * c.planning_worst:.1f} % "
            "of the measured OCC from 0.8 to 1.3 pu",
            highlight=False,
        )
    for line in c.left_out + c.notes:
        console.print(f"note: {line}", highlight=False)
    if args.json:
        write_json(args.json, {"characteristics": c.as_dict(), **result_provenance(args.sheet)})
        console.print(f"wrote {args.json}")
    return 0
