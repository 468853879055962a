"""``phid identify``: input -> three-stage identification -> table, JSON, optional HTML report."""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

from rich.console import Console

from phid_ros.api import UnitIdentification, cut_unit, identify_unit
from phid_ros.cli.common import finish, load_truth, step_thresholds, warn
from phid_ros.cli.progress import ProgressLine
from phid_ros.cli.tables import NOT_IDENTIFIED, NOT_IDENTIFIED_MEANS, Col, fmt, pct, print_table, withheld_text
from phid_ros.controls.fit import ControlFit
from phid_ros.controls.models import KINDS_IN_ORDER, MODELS
from phid_ros.day_summary import HEADERS, day_summary
from phid_ros.ident.constraints import parse_constraints
from phid_ros.ident.pipeline import IdentificationResult, IdentifyOptions
from phid_ros.ident.route_figures import FieldCircuitFigures
from phid_ros.io.files.results import write_json
from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME, SYMBOLS, GeneratorParameters

# imported here, with the command, so that their import is start-up and not "reading"


def _err(v: float, t: float | None) -> str:
    if t is None or not math.isfinite(v) or t == 0:
        return ""
    return pct(100 * (v / t - 1))


def print_parameters(console: Console, res: IdentificationResult, truth: GeneratorParameters | None) -> None:
    t = truth.as_dict() if truth else {}
    published = res.published()
    cols = [Col("param", "left"), Col("unit", "left"), Col("IEEE 115", keep=3), Col("err 115", keep=2)]
    cols += [Col("proposed"), Col("± std"), Col("err"), Col("truth", keep=4), Col("note", "left", keep=5, text=True)]
    rows = []
    for name in PARAMETER_NAMES:
        est = res.estimates.get(name)
        base = res.baseline.get(name)
        shown = name in published
        v = est.value if est is not None and shown else math.nan
        note = "missing" if est is None else ("" if est.identifiable else "not identified")
        if name in res.constraints.fixed:
            note = "held (--fix)"
        rows.append(
            [
                SYMBOLS[name],
                SPECS_BY_NAME[name].unit,
                fmt(base.value if base else math.nan) + ("*" if base and base.at_bound else ""),
                _err(base.value, t.get(name)) if base else "",
                fmt(v, 5) if est is None or shown else withheld_text(est),
                fmt(est.std if est is not None and shown else math.nan, 2),
                _err(v, t.get(name)),
                fmt(t[name]) if truth else "",
                note,
            ]
        )
    if not truth:
        cols, rows = _without(cols, rows, ("err 115", "err", "truth"))
    if not res.baseline:
        cols, rows = _without(cols, rows, ("IEEE 115", "err 115"))
    legend = "err = (estimate / truth - 1); IEEE 115: the standard's test-based method; * = at its search bound"
    withheld = f"{NOT_IDENTIFIED} = {NOT_IDENTIFIED_MEANS} (in the JSON: null, the value under 'withheld')"
    said = [w for w, shown in ((legend, truth), (withheld, len(published) < len(res.estimates))) if shown]
    print_table(console, f"identified parameters (method: {res.method})", cols, rows, "; ".join(said))


def _without(cols: list[Col], rows: list[list[str]], names: tuple[str, ...]) -> tuple[list[Col], list[list[str]]]:
    keep = [i for i, c in enumerate(cols) if c.header not in names]
    return [cols[i] for i in keep], [[r[i] for i in keep] for r in rows]


def print_controls(console: Console, found: dict[str, ControlFit | str]) -> None:
    """The exciter, governor and stabiliser: the model named and its constants (PSS/E's names; not
    those its structure holds, a torsional filter left out), or why none."""
    rows = []
    for kind, f in found.items():
        if not isinstance(f, ControlFit):
            rows.append([kind, "none", f, ""])
            continue
        held = {p.name for p in MODELS[f.model].parameters if p.held}
        constants = ", ".join(
            f"{n} {v:.4g}" + ("" if f.identifiable[n] else " n.d.")
            for n, v in f.parameters.items()
            if v is not None and n not in held
        )
        rows.append([kind, f.model if f.named else "none", constants if f.named else f.why, f"{f.fit_rmse:.2e}"])
    cols = [
        Col("system", "left"),
        Col("model", "left"),
        Col("constants (± in the JSON)", "left", text=True),
        Col("RMSE pu"),
    ]
    reached = [f"{f.model} {', '.join(f.limits)}" for f in found.values() if isinstance(f, ControlFit) and f.limits]
    limits = f"limits reached: {'; '.join(reached)}; the others" if reached else "limits"
    title = "excitation, turbine-governor and stabiliser"
    print_table(console, f"{title} ({limits} never reached: not determined)", cols, rows)


def print_validation(console: Console, res: IdentificationResult) -> None:
    if res.validation is None or not res.validation.scenarios:
        return
    v = res.validation
    cols = [
        Col("scenario", "left"),
        Col("RMS δ°"),
        Col("max δ°", keep=4),
        Col("RMS ω%"),
        Col("RMSE", keep=2),
        Col("MAE", keep=1),
        Col("STD", keep=1),
        Col("max ΔP"),
        Col("max ΔQ"),
        Col("MOD-026", "left"),
    ]
    rows = [
        [
            m.scenario,
            f"{m.rms_delta_deg:.4f}",
            f"{m.max_delta_deg:.4f}",
            f"{m.rms_omega_pct:.5f}",
            f"{m.rmse:.1e}",
            f"{m.mae:.1e}",
            f"{m.std:.1e}",
            f"{m.max_dp:.4f}",
            f"{m.max_dq:.4f}",
            "pass" if m.mod026_pass else "FAIL",
        ]
        for m in v.scenarios
    ]
    print_table(
        console,
        f"validation against the {v.against} (Tables 8, 9)",
        cols,
        rows,
        "RMSE, MAE, STD of the state-trajectory error and max ΔP, ΔQ in pu; MOD-026: |ΔP|, |ΔQ| ≤ 0.05 pu",
    )


def print_day(console: Console, res: IdentificationResult, controls: dict[str, ControlFit | str]) -> None:
    """What each test gave (a recorder's day: the field-circuit routes, the exciter's steps)."""
    rows = [r.cells() for r in day_summary(res, controls)]
    cols = [
        Col(HEADERS[0], "left", key=True, breakable=True),
        Col(HEADERS[1]),
        Col(HEADERS[2], "left", keep=2),
        Col(HEADERS[3], "left", keep=5),
        Col(HEADERS[4], "left", keep=4),
        Col(HEADERS[5], "left", text=True),
    ]
    print_table(console, "what each test gave", cols, rows)


def start_from_dyr(args: Any) -> dict[str, dict[str, float]]:
    """``--start-from UNIT.dyr``: the user's existing model as the starts of the searches that
    take one (the machine's, as --start does; the controls' fits), and its control models as the
    candidates unless --exciter/--governor/--stabiliser name others. Returns the controls' starts by kind."""
    from phid_ros.export.dyr_read import read_unit

    unit = read_unit(args.start_from)
    given = {item.partition("=")[0] for item in (*args.start, *args.fix)}
    machine = unit.fourth_order(p_m0=0.0)  # the searches are the fourth-order model's
    for name in ("H", "X_d", "X_q", "X_d_prime", "X_q_prime", "T_d0_prime", "T_q0_prime"):
        if name not in given:  # D leaves out: the .dyr's is PSS/E's form, and stage 1 takes no start
            args.start.append(f"{name}={getattr(machine, name)!r}")
    for kind, settings in unit.controls.items():
        if not getattr(args, kind, None):
            setattr(args, kind, [settings.model])
    return {kind: dict(settings.values) for kind, settings in unit.controls.items()}


def read_sisters(paths: list[str]) -> list[tuple[str, dict[str, Any]]]:
    """The sister units' results (``--sister``), read before the identification: a file that is not
    a results document is refused by name, not found out after minutes."""
    from phid_ros.io.files.results import ResultsError, read_json

    out = []
    for path in paths:
        doc = read_json(path)
        if not isinstance(doc.get("parameters"), dict) or not isinstance(doc.get("uncertainty"), dict):
            raise ResultsError(f"{path}: not an identification's results (no 'parameters' and 'uncertainty'): --sister")
        out.append((path, doc))
    return out


def compare_sisters(here: str, doc: dict[str, Any], sisters: list[tuple[str, dict[str, Any]]]) -> dict[str, Any]:
    """This identification against each sister unit's result, by the fleet's rule (``sister_gaps``:
    both well identified and further apart than SISTER_SIGMAS combined stds): one design, one
    machine, so one of the two sets (or a unit) is not what it should be."""
    from phid_ros.fleet.history import SISTER_SIGMAS, row_of_result, sister_gaps

    design = "declared with --sister"
    mine = row_of_result(here, doc, design)
    apart = []
    for path, other in sisters:
        for g in sister_gaps([mine, row_of_result(path, other, design)]):
            ours, theirs = (g.first, g.second) if g.first is mine else (g.second, g.first)
            n = g.parameter
            v, s, w, t = ours.values[n], ours.stds[n], theirs.values[n], theirs.stds[n]
            said = (
                f"{SYMBOLS[n]}: {v:.4g} ± {s:.2g} here, {w:.4g} ± {t:.2g} in the sister unit's {path} "
                f"({w / v - 1.0:+.1%} there, {g.sigmas:.1f} σ apart: one design, so one of the two is not "
                "what it should be)"
            )
            apart.append(
                {"parameter": n, "sister": path, "here": v, "here_std": s, "there": w, "there_std": t}
                | {"sigmas": g.sigmas, "said": said}
            )
    return {"compared_with": [p for p, _ in sisters], "sigmas": SISTER_SIGMAS, "apart": apart}


def open_circuit_curve_text(curve: dict[str, Any]) -> str:
    """The open-circuit curve the no-load plateaus gave (``ident.open_circuit_curve``), in one line."""

    def said(name: str, e: dict[str, Any]) -> str:
        if e["identifiable"]:
            return f"{name} {e['value']:.4f} ± {e['std']:.4f}"
        value = e["value"]
        return f"{name} not measured" + (f" (the form puts it at {value:.3g})" if value == value else "")

    head = f"open-circuit curve from the no-load plateaus ({'; '.join(curve['notes'])})"
    if curve["quadratic"]["A"] != curve["quadratic"]["A"]:  # NaN: no curve fitted
        return f"{head}: the plateaus lie up to {100 * curve['worst_relative_error']:.1f} % off the air-gap line"
    by = curve.get("worst_relative_error_by_branch") or {}
    branches = ", ".join(f"{b} {100 * w:.1f} %" for b, w in by.items())
    return (
        f"{head}: "
        f"{said('S(1.0)', curve['S10'])}, {said('S(1.2)', curve['S12'])}; within "
        f"{100 * curve['worst_relative_error']:.1f} % of the plateaus' field current"
        + (f" ({branches})" if branches else "")
    )


def field_resistance_text(r: dict[str, Any]) -> str:
    """The field winding's resistance from the plateaus (``api.field_resistance_of``), in one line."""
    files = len(r["files"])
    lo, hi = r["range"]
    spread = f", files {lo:#.4g}-{hi:#.4g} (the winding's temperature)" if files > 1 else ""
    unit = " Ω" if r["unit"] == "ohm" else " (U_f per I_f as recorded: the recordings state no field bases in V and A)"
    left = f"; left out, without field bases: {', '.join(r['left_out'])}" if r.get("left_out") else ""
    said = f"{r['value']:#.4g}{unit} over {files} test file(s)"
    return f"field winding's resistance at the plateaus: {said}{spread}{left}"


def print_identified(
    console: Console, found: UnitIdentification, truth: GeneratorParameters | None, fixed: Mapping[str, float]
) -> None:
    """identify's text: what a recorder's channels determine, the parameters, the checks, the
    controls, the no-load curve and R_f where found, and the paper's stage 1a beside."""
    scenarios, res, controls = found.scenarios, found.result, found.controls
    if res.determined_by:  # a recorder's channel set: say first what it determines and how
        from phid_ros.cli.tables import print_determinable
        from phid_ros.ident.determinable import plan

        planned = plan(scenarios, fixed)
        print_determinable(console, "what these channels determine", planned, res.determined_by)
    print_parameters(console, res, truth)
    print_validation(console, res)
    print_controls(console, controls)
    no_load = res.route_details.get("field_circuit")
    if isinstance(no_load, FieldCircuitFigures) and no_load.curve is not None:
        console.print(open_circuit_curve_text(no_load.curve.as_dict()), highlight=False, markup=False)
    if resistance := res.route_details.get("field_resistance"):
        console.print(field_resistance_text(resistance.as_dict()), highlight=False, markup=False)
    if res.determined_by:
        print_day(console, res, controls)
    if found.no_load is not None:
        from phid_ros.cli.validate import print_checks

        print_checks(console, f"the no-load tests played with {found.no_load.unit}", found.no_load)
    if res.stage1_paper is not None:
        console.print(
            f"for comparison, not in the result: the paper's differential damping (stage 1a) gives H = "
            f"{res.stage1_paper.H.value:.4f} s, D = {res.stage1_paper.D.value:.4f} pu (the table's H, D "
            "are stage 1's swing regression, the ones published)",
            highlight=False,
        )


def identify_command(args: Any, console: Console) -> int:
    from phid_ros.io.files.outputs import refuse_inputs

    refuse_inputs(
        [args.json, args.report],
        [*args.input, args.truth, getattr(args, "start_from", None), *(getattr(args, "sister", None) or [])],
    )
    control_starts = start_from_dyr(args) if getattr(args, "start_from", None) else {}
    # a typo said before the reading
    constraints = parse_constraints(args.fix, args.bounds, args.start, args.saturation)
    sisters = read_sisters(getattr(args, "sister", None) or [])
    t_start = time.perf_counter()
    with ProgressLine(f"reading {' + '.join(args.input)}") as progress:
        # read part by part where the recording allows: only the scenarios' windows are kept
        unit = cut_unit(args.input, step_thresholds(args), progress.update)
        for w in [*unit.notes, *(w for c in unit.cuts for w in c.recording.warnings)]:
            warn(w)
        t_read = time.perf_counter() - t_start
        truth = load_truth(args.truth, unit.recording) if args.truth else None
        options = IdentifyOptions(
            method=args.method,
            seed=args.seed,
            baseline=not args.no_baseline,
            paper_maxiter=args.paper_maxiter,
            step_thresholds=step_thresholds(args),
            constraints=constraints,
        )
        candidates = {k: names for k in KINDS_IN_ORDER if (names := getattr(args, k, None))}
        found = identify_unit(
            unit, options, truth, candidates=candidates, control_starts=control_starts, progress=progress.update
        )
    scenarios, res, controls, doc = found.scenarios, found.result, found.controls, found.document
    source = unit.source
    res.timing = {"read": round(t_read, 6), **res.timing}
    doc["timing_s"] = res.timing
    if sisters:
        doc["sisters"] = compare_sisters(source, doc, sisters)
        for gap in doc["sisters"]["apart"]:
            warn(gap["said"])
    if args.json:
        t0 = time.perf_counter()
        write_json(args.json, doc)
        res.timing["write_json"] = round(time.perf_counter() - t0, 6)
    res.timing["total"] = round(time.perf_counter() - t_start, 6)
    if args.json:  # the JSON carries the final timing too
        doc["timing_s"] = res.timing
        write_json(args.json, doc)
    print_identified(console, found, truth, constraints.fixed)

    def report(out: Any) -> None:
        from phid_ros.cli.report import write_report

        write_report(out, res, truth, source, controls, found.no_load)

    summary = f"identified from {len(scenarios)} scenarios in {res.timing['total']:.3f} s (wall time)"
    return finish(console, res.problems, summary, args.json, args.report, report)
