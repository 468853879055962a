"""``phid diagnose``: input -> identification -> gap localisation -> named effects -> table, JSON, report."""

from __future__ import annotations

import textwrap
import time
from typing import Any

from rich.console import Console

from phid_ros.api import cut_scenarios, identify_scenarios, result_provenance
from phid_ros.cli.common import finish, load_truth, step_thresholds, warn
from phid_ros.cli.progress import ProgressLine
from phid_ros.cli.tables import CHANNEL_LABELS, Col, effect_values_text, fmt, pct, print_table, signed_int
from phid_ros.diagnose.localise import localise
from phid_ros.diagnose.options import DiagnoseOptions
from phid_ros.diagnose.results import is_determined, to_json
from phid_ros.diagnose.workflow import diagnose
from phid_ros.errors import PhidError
from phid_ros.ident.pipeline import IdentifyOptions
from phid_ros.ident.plant_playin import OUTPUTS
from phid_ros.io.files.results import read_json, write_json
from phid_ros.model.parameters import PARAMETER_NAMES, SYMBOLS


def print_before_after(console: Console, doc: dict[str, Any]) -> None:
    cols = [Col("channel", "left"), Col("unit", "left"), Col("RMSE before", keep=3), Col("RMSE after", keep=3)]
    cols += [Col("unexpl. before"), Col("unexpl. after"), Col("change")]
    rows = []
    for c in OUTPUTS:
        e = doc["channels"][c]
        ub, ua = e["unexplained_before"], e["unexplained_after"]
        symbol, unit = CHANNEL_LABELS[c]
        change = pct(100 * (ua / ub - 1), 0) if ub > 0 else "-"
        rows.append([symbol, unit, fmt(e["rmse_before"], 3), fmt(e["rmse_after"], 3), fmt(ub, 3), fmt(ua, 3), change])
    b, a = doc["rmse_before"], doc["rmse_after"]
    rows.append(["overall", "σ", "", "", fmt(b, 3), fmt(a, 3), pct(100 * (a / b - 1), 0) if b > 0 else "-"])
    print_table(
        console,
        "held-out scenarios: model vs measurement, before and after adding the named effects",
        cols,
        rows,
        "unexpl. = the residual with its white-noise share removed; overall in units of the sensor noise σ",
    )


def print_parameters(console: Console, doc: dict[str, Any]) -> None:
    truth = doc.get("truth")
    cols = [Col("param", "left"), Col("identified"), Col("refit 4th", keep=3), Col("after")]
    if truth:
        cols += [Col("truth"), Col("err ident."), Col("err after")]
    rows = []
    for n in PARAMETER_NAMES:
        # a value the identification left at a search bound is a bound, not a value
        bound = " at bound" if n in doc.get("parameters_identified_at_bound", ()) else ""
        row = [SYMBOLS[n], fmt(doc["parameters_identified"][n]) + bound, fmt(doc["parameters_base_refit"][n])]
        # n.d.: the data do not determine it (a two-point profile, diagnose.determinability.determined)
        row.append(fmt(doc["parameters"][n]) + ("" if is_determined(doc, n) else " n.d."))
        if truth:
            e = doc["errors_pct"]
            row += [fmt(truth[n]), pct(e["identified"][n]), pct(e["after"][n])]
        rows.append(row)
    print_table(console, "base parameters", cols, rows)
    if not all(is_determined(doc, n) for n in PARAMETER_NAMES):
        console.print("n.d. = not determined by these data: held 10 % away, the rest refit as well (warnings)")


def print_rounds(console: Console, doc: dict[str, Any]) -> None:
    cols = [Col("rnd", key=True), Col("candidate", "left", key=True), Col("ΔBIC"), Col("held-out")]
    cols += [Col("named", "left"), Col("fitted values", "left", text=True)]
    rows = []
    for i, r in enumerate(doc["rounds"], start=1):
        for tr in r["trials"]:
            gain = tr["heldout_gain"]
            rows.append(
                [
                    str(i),
                    tr["candidate"],
                    "-" if tr["delta_bic"] is None else signed_int(tr["delta_bic"]),
                    "-" if gain is None else pct(-100 * gain, 0),
                    "yes" if tr["accepted"] else "",
                    effect_values_text(tr["parameters"] or {}),
                ]
            )
    print_table(console, "candidates (each fitted with the base parameters refitted)", cols, rows)


def diagnose_command(args: Any, console: Console) -> int:
    t_start = time.perf_counter()
    if args.workers < 0:
        raise PhidError(f"--workers {args.workers}: give 0 (every core) or a positive number of processes")
    from phid_ros.io.files.outputs import refuse_inputs

    refuse_inputs([args.json, args.report], [args.input, args.truth])
    with ProgressLine(f"reading {args.input} and cutting its scenarios") as progress:
        source = str(args.input)
        # part by part: only the windows are held through minutes of fitting, not the recording
        cut = cut_scenarios(args.input, step_thresholds(args))
        for w in cut.recording.warnings:
            warn(w)
        truth = load_truth(args.truth, cut.recording) if args.truth else None
        truth_effects = read_json(args.truth).get("effects") if args.truth else None
        scenarios, problems = cut.scenarios, cut.problems
        f_hz = cut.f_nominal_hz
        if not any(s.role == "identify" for s in scenarios):
            raise PhidError(f"{source}: no identification scenarios; the diagnosis needs them to fit candidate models")
        missing = sorted({c for s in scenarios for c in s.absent})
        if missing:
            raise PhidError(
                f"{source}: not recorded: {', '.join(missing)}; the diagnosis plays the model in against every "
                "channel (phid identify determines what these channels allow)"
            )
        opts = IdentifyOptions(baseline=False, validate=False, f_nominal_hz=f_hz)
        res = identify_scenarios(scenarios, source, opts, progress=progress.update)
        start = res.parameters
        model = res.complete()
        progress.update("locating the gap between the model and the measurements")
        gap = localise(scenarios, model, f_hz) if model is not None else None
        d = diagnose(
            scenarios,
            start,
            DiagnoseOptions.after(res, f_nominal_hz=f_hz, workers=args.workers, scheduler=args.scheduler),
            progress=progress.update,
        )
    first_fit = [p for p in res.problems if p not in res.label_disputes]
    own = list(d.problems)
    d.problems[:0] = problems + first_fit
    doc = to_json(d, truth, truth_effects)
    doc.update(result_provenance(args.input))
    if gap is not None:
        doc["gap_before"] = gap.as_dict()
    doc["seconds"] = time.perf_counter() - t_start
    if args.json:
        write_json(args.json, doc)
    print_rounds(console, doc)
    print_before_after(console, doc)
    print_parameters(console, doc)
    if doc["effects"]:
        named = ", ".join(f"{e['name']} ({effect_values_text(e['parameters'], e)})" for e in doc["effects"])
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

    def report(out: Any) -> None:
        from phid_ros.cli.diagnose_report import write_report

        write_report(out, d, doc, source)

    if doc["effects"] and first_fit:
        # what the fourth-order fit got wrong is what the named effects explain: said as that, not
        # as warnings after the result, where they read as the diagnosis having failed
        console.print("the first identification (column 'identified') showed the missing physics as:", highlight=False)
        for p in first_fit:
            item = textwrap.fill(p, width=console.width, initial_indent="  - ", subsequent_indent="    ")
            console.print(item, highlight=False, markup=False, soft_wrap=True)
        first_fit = []
    summary = f"diagnosed in {doc['seconds']:.1f} s (wall time)"
    return finish(console, problems + first_fit + own, summary, args.json, args.report, report)
