"""``phid diagnose``: input -> identification -> gap localisation -> named effects -> table, JSON, report."""

from __future__ import annotations

import time
from typing import Any

from rich.console import Console
from rich.table import Table

from phid_ros.cli.common import warn
from phid_ros.cli.identify import SYMBOLS, load_input, load_truth
from phid_ros.cli.scenarios import scenarios_from_recording
from phid_ros.diagnose.localise import localise
from phid_ros.diagnose.playin import OUTPUTS
from phid_ros.diagnose.results import to_json
from phid_ros.diagnose.workflow import DiagnoseOptions, diagnose
from phid_ros.errors import PhidError
from phid_ros.ident.pipeline import IdentifyOptions, identify
from phid_ros.io.results import read_json, write_json
from phid_ros.model.parameters import PARAMETER_NAMES

UNITS = {"omega": "pu", "delta": "rad", "i_d": "pu", "i_q": "pu", "p_e": "pu", "q_e": "pu"}


def before_after_table(doc: dict[str, Any]) -> Table:
    t = Table(title="Held-out scenarios: model vs measurement, before and after adding the named effects")
    for col in ("channel", "unit", "RMSE before", "RMSE after", "unexplained before", "unexplained after", "change"):
        t.add_column(col, justify="left" if col in ("channel", "unit") else "right")
    for c in OUTPUTS:
        e = doc["channels"][c]
        ub, ua = e["unexplained_before"], e["unexplained_after"]
        change = f"{100 * (ua / ub - 1):+.0f} %" if ub > 0 else "-"
        t.add_row(c, UNITS[c], f"{e['rmse_before']:.3g}", f"{e['rmse_after']:.3g}", f"{ub:.3g}", f"{ua:.3g}", change)
    b, a = doc["rmse_before"], doc["rmse_after"]
    t.add_row("overall", "σ", "", "", f"{b:.3g}", f"{a:.3g}", f"{100 * (a / b - 1):+.0f} %" if b > 0 else "-")
    return t


def parameter_table(doc: dict[str, Any]) -> Table:
    truth = doc.get("truth")
    t = Table(title="Base parameters")
    cols = ["parameter", "identified", "refit (4th order)", "after"] + (
        ["truth", "err identified", "err after"] if truth else []
    )
    for col in cols:
        t.add_column(col, justify="left" if col == "parameter" else "right")
    for n in PARAMETER_NAMES:
        row = [SYMBOLS[n], f"{doc['parameters_identified'][n]:.4g}", f"{doc['parameters_base_refit'][n]:.4g}"]
        row.append(f"{doc['parameters'][n]:.4g}")
        if truth:
            e = doc["errors_pct"]
            row += [f"{truth[n]:.4g}", f"{e['identified'][n]:+.2f} %", f"{e['after'][n]:+.2f} %"]
        t.add_row(*row)
    return t


def rounds_table(doc: dict[str, Any]) -> Table:
    t = Table(title="Candidates (each fitted with the base parameters refitted)")
    for col in ("round", "candidate", "ΔBIC", "held-out change", "named", "fitted values"):
        t.add_column(col, justify="right" if col in ("ΔBIC", "held-out change") else "left")
    for i, r in enumerate(doc["rounds"], start=1):
        for tr in r["trials"]:
            vals = tr["parameters"] or {}
            text = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in vals.items())
            gain = tr["heldout_gain"]
            t.add_row(
                str(i),
                tr["candidate"],
                "-" if tr["delta_bic"] is None else f"{tr['delta_bic']:+.0f}",
                "-" if gain is None else f"{-100 * gain:+.0f} %",
                "yes" if tr["accepted"] else "",
                text,
            )
    return t


def run(args: Any, console: Console) -> int:
    t_start = time.perf_counter()
    if args.workers < 0:
        raise PhidError(f"--workers {args.workers}: give 0 (every core) or a positive number of processes")
    from phid_ros.io.outputs import refuse_inputs

    refuse_inputs([args.json, args.report], [args.input, args.truth])
    rec, source = load_input(args.input)
    truth = load_truth(args.truth, rec) if args.truth else None
    truth_effects = read_json(args.truth).get("effects") if args.truth else None
    scenarios, problems = scenarios_from_recording(rec, source)
    if not any(s.role == "identify" for s in scenarios):
        raise PhidError(f"{source}: no identification scenarios; the diagnosis needs them to fit candidate models")
    opts = IdentifyOptions(baseline=False, validate=False, f_nominal_hz=rec.f_nominal_hz)
    with console.status("identifying the fourth-order model") as status:
        res = identify(scenarios, opts)
        start = res.parameters
        model = res.complete()
        gap = localise(scenarios, model, rec.f_nominal_hz) if model is not None else None

        def progress(msg: str) -> None:
            status.update(msg)

        d = diagnose(
            scenarios,
            start,
            DiagnoseOptions(f_nominal_hz=rec.f_nominal_hz, workers=args.workers, scheduler=args.scheduler),
            progress=progress,
        )
    d.problems[:0] = problems + [p for p in res.problems if "kept the label" not in p]
    doc = to_json(d, truth, truth_effects)
    doc["input"] = source
    if gap is not None:
        doc["gap_before"] = gap.as_dict()
    doc["seconds"] = time.perf_counter() - t_start
    if args.json:
        write_json(args.json, doc)
    console.print(rounds_table(doc))
    console.print(before_after_table(doc))
    console.print(parameter_table(doc))
    if doc["effects"]:
        named = ", ".join(f"{e['name']} ({_fmt_values(e['parameters'])})" for e in doc["effects"])
        console.print(f"missing physics: {named}", highlight=False)
    else:
        console.print("nothing is missing: no candidate effect improves the model on both fit and held-out data")
    if truth is not None:
        m = doc["mean_abs_error_pct"]
        console.print(
            f"mean |error| of the eight base parameters: identified {m['identified']:.2f} %, "
            f"fourth-order refit {m['base_refit']:.2f} %, after {m['after']:.2f} %",
            highlight=False,
        )
    for p in d.problems:
        warn(p)
    console.print(f"{doc['seconds']:.1f} s" + (f", wrote {args.json}" if args.json else ""), highlight=False)
    if args.report:
        from phid_ros.cli.diagnose_report import write_report

        write_report(args.report, d, doc, source)
        console.print(f"wrote {args.report}", highlight=False)
    return 0


def _fmt_values(values: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in values.items())
