"""phid validate: a unit's PSS/E record against a recording, as MOD-026/027 ask (exit 0: all
checks pass; 1: a check fails; 2: bad input)."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

from rich.console import Console

from phid_ros.api import validate_record
from phid_ros.cli.common import figure_backend, step_thresholds, warn
from phid_ros.cli.progress import ProgressLine
from phid_ros.cli.report import STYLE, html_table, png_data_uri
from phid_ros.cli.tables import Col, print_table
from phid_ros.controls.unit_validation import (
    CHANNELS,
    ChannelCheck,
    ScenarioCheck,
    UnitValidation,
)
from phid_ros.io.files.outputs import write_text
from phid_ros.io.files.results import write_json


def validate_command(args: Any, console: Console) -> int:
    from phid_ros.io.files.outputs import refuse_inputs

    refuse_inputs([args.json, args.report], [args.dyr, args.input])
    with ProgressLine(f"reading {args.input} and cutting its scenarios") as progress:
        found = validate_record(
            args.dyr,
            args.input,
            bus=args.bus,
            machine_id=args.id,
            thresholds=step_thresholds(args),
            progress=progress.update,
        )
    for w in found.warnings:
        warn(w)
    if args.json:
        write_json(args.json, found.document)
    if args.report:
        write_report(args.report, found.result, str(args.input))
    print_result(console, found.result)
    return 0 if found.result.passed() else 1


def print_result(console: Console, result: UnitValidation) -> None:
    rows = [
        [
            s.scenario,
            s.kind,
            f"{c.standard} {CHANNELS[c.channel][1]}",
            c.simulated_by,
            f"{c.max_error:.4f}",
            f"{c.band:.4f}",
            "pass" if c.passed else "FAIL",
        ]
        for s in result.scenarios
        for c in s.checks
    ]
    cols = [
        Col("scenario", "left", key=True, breakable=True),
        Col("kind", "left", keep=3),
        Col("check", "left"),
        Col("simulated by", "left", keep=4),
        Col("max |err| pu"),
        Col("band pu"),
        Col("", "left"),
    ]
    print_table(console, f"MOD-026/027: {result.unit}", cols, rows)
    for n in result.notes:
        console.print(f"note: {n}", highlight=False)
    for standard in ("MOD-026", "MOD-027"):
        checks = [c for s in result.scenarios for c in s.checks if c.standard == standard]
        if checks:
            failed = sum(not c.passed for c in checks)
            verdict = "pass" if not failed else f"FAIL ({failed} of {len(checks)} checks)"
            console.print(f"{standard}: {verdict}", highlight=False)


def _verdict(c: ChannelCheck) -> str:
    return f"{c.standard} {CHANNELS[c.channel][1]}: {'pass' if c.passed else 'FAIL'}"


def _overlay(s: ScenarioCheck) -> str:
    import matplotlib.pyplot as plt

    shown = list(s.checks)
    fig, axes = plt.subplots(1, len(shown), figsize=(3.6 * len(shown), 2.8), squeeze=False)
    for ax, c in zip(axes[0], shown):
        rec, sim = s.recorded[c.channel], s.simulated[c.channel]
        ax.fill_between(s.t, rec - c.band, rec + c.band, color="0.88", lw=0, label=f"band ±{c.band:.3g}")
        ax.plot(s.t, rec, color="k", lw=1.0, label="recorded")
        ax.plot(s.t, sim, color="tab:red" if not c.passed else "tab:blue", lw=1.4, label=f"{c.simulated_by}")
        ax.set_title(f"{c.standard} {CHANNELS[c.channel][1]}: {'pass' if c.passed else 'FAIL'}", fontsize=9)
        ax.set_xlabel("t (s)")
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    return png_data_uri(fig)


def write_report(path: str | Path, result: UnitValidation, source: str) -> Path:
    figure_backend()
    rows = [[s.scenario, s.kind] + [_verdict(c) for c in s.checks] for s in result.scenarios]
    width = max((len(r) for r in rows), default=2)
    rows = [r + [""] * (width - len(r)) for r in rows]
    headers = ["scenario", "kind"] + ["check"] * (width - 2)
    figures = "".join(
        f"<h3>{html.escape(s.scenario)} ({html.escape(s.kind)})</h3>"
        + f'<img src="{_overlay(s)}" alt="{html.escape(s.scenario)}">'
        + "".join(f"<p class=note>{html.escape(n)}</p>" for n in s.notes)
        for s in result.scenarios
        if s.checks
    )
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in result.notes) or "<li>none</li>"
    tol = result.as_json()["tolerances"]
    doc = f"""<!doctype html><html><head><meta charset="utf-8"><title>phid validate: {html.escape(source)}</title>
<style>{STYLE}</style></head><body>
<h1>MOD-026/027 validation</h1>
<p>Unit: <code>{html.escape(result.unit)}</code> &middot; recording: <code>{html.escape(source)}</code></p>
<p>MOD-026 (excitation: Q, E_fd): <b>{"pass" if result.passed("MOD-026") else "FAIL"}</b> &middot;
MOD-027 (turbine-governor: P, P_m): <b>{"pass" if result.passed("MOD-027") else "FAIL"}</b></p>
<p>The unit played in with the recorded terminal voltage (magnitude, angle); the exciter driven by the
recorded V_t, the governor by the recorded speed. Bands: P, Q {html.escape(tol["p_e, q_e"])}; E_fd, P_m
{html.escape(tol["v_f, p_m"])}.</p>
{html_table(headers, rows, text_columns=range(width))}
<h2>Notes</h2><ul>{notes}</ul>
<h2>Recorded against simulated</h2>
{figures}
</body></html>"""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_text(p, doc)
    return p
