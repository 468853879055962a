"""``phid identify``: input -> three-stage identification -> table, JSON, optional HTML report."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from phid_ros.cli.common import read_input, warn

# imported here, with the command, so that their import is start-up and not "reading"
from phid_ros.cli.scenarios import scenarios_from_recording
from phid_ros.errors import PhidError, ResultsError
from phid_ros.ident.pipeline import IdentificationResult, IdentifyOptions, identify
from phid_ros.ident.scenario import ScenarioData
from phid_ros.io.recording import Recording
from phid_ros.io.results import read_json, write_json
from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME, GeneratorParameters

SYMBOLS = {
    "H": "H",
    "D": "D",
    "X_d": "X_d",
    "X_q": "X_q",
    "X_d_prime": "X'_d",
    "X_q_prime": "X'_q",
    "T_d0_prime": "T'_d0",
    "T_q0_prime": "T'_q0",
}


def load_input(path: str | Path) -> tuple[Recording, str]:
    """A rosbag2 folder, a single .mcap, or a CSV manifest.json (warnings on stderr)."""
    return read_input(path)


def load_truth(path: str | Path, rec: Recording) -> GeneratorParameters:
    doc = read_json(path)
    values = doc.get("parameters", doc)
    if not isinstance(values, dict):
        raise ResultsError(f"{path}: 'parameters' must be an object of the eight parameters")
    truth = GeneratorParameters.from_mapping(values, source=str(path))
    f_truth = doc.get("f_nominal_hz")
    if f_truth is not None and "f_nominal_hz" in rec.metadata and abs(float(f_truth) - rec.f_nominal_hz) > 1e-9:
        raise PhidError(f"{path}: nominal frequency {f_truth} Hz differs from the recording's {rec.f_nominal_hz} Hz")
    base_truth = doc.get("base_mva")
    base_rec = rec.metadata.get("base_mva")
    if base_truth is not None and base_rec is not None and abs(float(base_truth) - float(base_rec)) > 1e-9:
        raise PhidError(
            f"{path}: base {base_truth} MVA differs from the recording's {base_rec} MVA; "
            "per-unit parameters on different bases do not compare"
        )
    return truth


def _fmt(v: float, digits: int = 4) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.{digits}g}"


def _err(v: float, t: float | None) -> str:
    if t is None or not math.isfinite(v) or t == 0:
        return ""
    return f"{100 * (v / t - 1):+.2f} %"


def parameter_table(res: IdentificationResult, truth: GeneratorParameters | None) -> Table:
    table = Table(title=f"identified parameters (method: {res.method})", title_justify="left")
    cols = (
        ["parameter", "unit", "IEEE 115"]
        + (["err"] if truth else [])
        + ["proposed", "± std"]
        + (["err", "truth"] if truth else [])
        + ["note"]
    )
    for c in cols:
        table.add_column(c, justify="left" if c in ("parameter", "unit", "note") else "right")
    t = truth.as_dict() if truth else {}
    for name in PARAMETER_NAMES:
        est = res.estimates.get(name)
        base = res.baseline.get(name)
        v = est.value if est else math.nan
        row = [
            SYMBOLS[name],
            SPECS_BY_NAME[name].unit,
            _fmt(base.value if base else math.nan) + (" (bound)" if base and base.at_bound else ""),
        ]
        if truth:
            row.append(_err(base.value, t[name]) if base else "")
        row += [_fmt(v, 5), _fmt(est.std if est else math.nan, 2)]
        if truth:
            row += [_err(v, t[name]), _fmt(t[name])]
        note = "" if est is None else ("not identified" if not est.identifiable else "")
        row.append(note if est is not None else "missing")
        table.add_row(*row)
    return table


def validation_table(res: IdentificationResult) -> Table | None:
    if res.validation is None:
        return None
    v = res.validation
    table = Table(
        title=f"validation against the {v.against} (Tables 8, 9; MOD-026 ±0.05 pu on P, Q)", title_justify="left"
    )
    for c in (
        "scenario",
        "RMS δ °",
        "max δ °",
        "RMS ω %",
        "RMSE pu",
        "MAE pu",
        "STD pu",
        "max ΔP",
        "max ΔQ",
        "MOD-026",
    ):
        table.add_column(c, justify="left" if c == "scenario" else "right")
    for m in v.scenarios:
        table.add_row(
            m.scenario,
            f"{m.rms_delta_deg:.4f}",
            f"{m.max_delta_deg:.4f}",
            f"{m.rms_omega_pct:.5f}",
            f"{m.rmse:.2e}",
            f"{m.mae:.2e}",
            f"{m.std:.2e}",
            f"{m.max_dp:.4f}",
            f"{m.max_dq:.4f}",
            "pass" if m.mod026_pass else "FAIL",
        )
    return table


def identify_recording(
    rec: Recording, source: str, options: IdentifyOptions, truth: GeneratorParameters | None = None
) -> tuple[list[ScenarioData], IdentificationResult]:
    """A recording's scenarios and their identification; PhidError when nothing could be identified."""
    scenarios, problems = scenarios_from_recording(rec, source)
    if not any(sc.role == "identify" for sc in scenarios):
        why = "; ".join(problems[-3:]) or f"{len(scenarios)} scenario(s), all for validation"
        raise PhidError(f"{source}: nothing to identify from: no usable identification scenario ({why})")
    res = identify(scenarios, options, truth)
    res.problems[:0] = problems
    if not any(e is not None and math.isfinite(e.value) for e in res.estimates.values()):
        raise PhidError(f"{source}: nothing identified: " + ("; ".join(res.problems) or "every stage failed"))
    return scenarios, res


def run(args: Any, console: Console) -> int:
    from phid_ros.io.outputs import refuse_inputs

    refuse_inputs([args.json, args.report], [args.input, args.truth])
    t_start = time.perf_counter()
    rec, source = load_input(args.input)
    t_read = time.perf_counter() - t_start
    truth = load_truth(args.truth, rec) if args.truth else None
    options = IdentifyOptions(
        method=args.method,
        f_nominal_hz=rec.f_nominal_hz,
        seed=args.seed,
        baseline=not args.no_baseline,
        paper_maxiter=args.paper_maxiter,
    )
    scenarios, res = identify_recording(rec, source, options, truth)
    res.timing = {"read": round(t_read, 6), **res.timing}
    doc = res.to_json(truth)
    doc["input"] = source
    if args.json:
        t0 = time.perf_counter()
        write_json(args.json, doc)
        res.timing["write_json"] = round(time.perf_counter() - t0, 6)
    res.timing["total"] = round(time.perf_counter() - t_start, 6)
    if args.json:  # the JSON carries the final timing too
        doc["timing_s"] = res.timing
        write_json(args.json, doc)
    console.print(parameter_table(res, truth))
    vt = validation_table(res)
    if vt is not None:
        console.print(vt)
    if res.stage1_paper is not None:
        console.print(
            f"paper's differential damping (stage 1a): H = {res.stage1_paper.H.value:.4f} s, "
            f"D = {res.stage1_paper.D.value:.4f} pu",
            highlight=False,
        )
    for p in res.problems:
        warn(p)
    console.print(
        f"{len(scenarios)} scenarios, {res.timing['total']:.3f} s" + (f", wrote {args.json}" if args.json else ""),
        highlight=False,
    )
    if args.report:
        from phid_ros.cli.report import write_report

        write_report(args.report, res, truth, source)
        console.print(f"wrote {args.report}", highlight=False)
    return 0
