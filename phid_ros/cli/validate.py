"""phid validate: a unit's PSS/E record against a recording, as MOD-026/027 ask (exit 0: all
checks pass; 1: a check fails; 2: bad input)."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

from rich.console import Console

from phid_ros.api import validate_record
from phid_ros.cli.common import figure_backend, step_thresholds, warn
from phid_ros.cli.html import STYLE, html_table, png_data_uri
from phid_ros.cli.progress import ProgressLine
from phid_ros.cli.tables import Col, print_table
from phid_ros.controls.unit_validation import (
    CHANNELS,
    STANDARD_OF,
    ChannelCheck,
    ScenarioCheck,
    UnitValidation,
)
from phid_ros.io.files.outputs import write_text
from phid_ros.io.files.results import write_json


def validate_command(args: Any, console: Console) -> int:
    from phid_ros.io.files.outputs import refuse_inputs

    refuse_inputs([args.json, args.report], [args.dyr, *args.input])
    with ProgressLine(f"reading {' + '.join(args.input)} and cutting its scenarios") as progress:
        found = validate_record(
            args.dyr,
            args.input,
            bus=args.bus,
            machine_id=args.id,
            thresholds=step_thresholds(args),
            progress=progress.update,
            open_loop=args.open_loop,
        )
    for w in found.warnings:
        warn(w)
    if args.json:
        write_json(args.json, found.document)
    if args.report:
        write_report(args.report, found.result, " + ".join(args.input))
    print_result(console, found.result)
    return 0 if found.result.passed() else 1


def print_result(console: Console, result: UnitValidation) -> None:
    print_checks(console, f"MOD-026/027: {result.unit}", result)
    console.print(why_larger_than_identify(result), highlight=False)
    for n in result.notes:
        console.print(f"note: {n}", highlight=False)


def print_checks(console: Console, title: str, result: UnitValidation) -> None:
    """The checks' table under ``title``, then each standard's verdict (validate's, and identify's
    no-load tests played on open circuit)."""
    rows = [[r[0], r[1], f"{r[2]} {r[3]}", *r[4:]] for r in check_rows(result)]
    cols = [
        Col("scenario", "left", key=True, breakable=True),
        Col("kind", "left", keep=3),
        Col("check", "left"),
        Col("simulated by", "left", keep=4),
        Col("max |err| pu"),
        Col("band pu"),
        Col("", "left"),
    ]
    print_table(console, title, cols, rows)
    for standard in ("MOD-026", "MOD-027"):
        checks = [c for s in result.scenarios for c in s.checks if c.standard == standard]
        if checks:
            console.print(f"{standard}: {verdict_text(result, standard)}", highlight=False)


def method_text(result: UnitValidation) -> str:
    """How the events were played, as they were: the loop closed on some, open on others."""
    checked = [s for s in result.scenarios if s.checks]
    exciter = [s for s in checked if s.made_by.get("v_f", "recorded") != "recorded"]
    closed = sum(s.loop_closed for s in exciter)
    text = "The unit played in with the recorded terminal voltage (magnitude, angle), "
    text += "the governor driven by the recorded speed; "
    if not exciter:
        return text + "no exciter played: E_fd as recorded."
    if closed == len(exciter):
        return text + "the exciter's loop closed through the machine (V_t, Q and E_fd as the unit makes them)."
    if not closed:
        return text + "the exciter driven by the recorded V_t (its loop open)."
    return (
        text + f"the exciter's loop closed through the machine on {closed} of {len(exciter)} events, on the others "
        "driven by the recorded V_t (each event's note says which)."
    )


def verdict_text(result: UnitValidation, standard: str) -> str:
    """``pass``, ``FAIL (k of n checks failed)``, or ``not tested`` with why (its control model never
    played: a P or Q checked with the recorded E_fd or P_m tests the machine, not the control)."""
    checks = [c for s in result.scenarios for c in s.checks if c.standard == standard]
    verdict = result.verdict(standard)
    if verdict is None:
        kind = next(k for k, v in STANDARD_OF.items() if v == standard)
        return f"not tested (no {kind} played: its output as recorded or held)"
    failed = sum(not c.passed for c in checks)
    return "pass" if not failed else f"FAIL ({failed} of {len(checks)} checks failed)"


def why_larger_than_identify(result: UnitValidation) -> str:
    """Why these errors exceed phid identify's for the same unit: a user comparing the two tables sees
    errors ~100x larger here and must not read that as a worse machine."""
    controls = sorted({c.simulated_by for s in result.scenarios for c in s.checks if c.channel in ("v_f", "p_m")})
    played = "the record as written (its model form and stated defaults"
    played += f"; its {' and '.join(controls)} making E_fd and P_m)" if controls else ")"
    return (
        f"These errors are not phid identify's max ΔP, ΔQ (often many times those): this plays {played}, where "
        "identify's validation plays the identified model itself with the recorded E_fd and P_m."
    )


UNITS = {"q_e": "Q (pu)", "v_f": "E_fd (pu, machine base)", "p_e": "P (pu)", "p_m": "P_m (pu)", "v_t": "V_t (pu)"}
ZOOM_S = 3.0  # an overlay shows this long either side of where its check is decided (its largest error)


def check_cells(c: ChannelCheck) -> list[str]:
    """One check as a table shows it: what was compared, by what, its error and band, the verdict
    (``CHECK_CELLS`` heads them); validate's tables and the replay report's record section."""
    return [
        c.standard,
        CHANNELS[c.channel][1],
        c.simulated_by,
        f"{c.max_error:.4f}",
        f"{c.band:.4f}",
        "pass" if c.passed else "FAIL",
    ]


CHECK_CELLS = ["standard", "channel", "simulated by", "max |error| (pu)", "band (pu)", "verdict"]


def check_rows(result: UnitValidation) -> list[list[str]]:
    """One row per check, the terminal's and the report's: the scenario, its kind, then :func:`check_cells`."""
    return [[s.scenario, s.kind, *check_cells(c)] for s in result.scenarios for c in s.checks]


CHECK_HEADERS = ["scenario", "kind", *CHECK_CELLS]


def overlay_figure(s: ScenarioCheck) -> Any:
    """Each checked channel of one event: the band about the recording, the simulation, and the
    recording drawn last so that a simulation on top of it never hides it."""
    import matplotlib.pyplot as plt

    shown = list(s.checks)
    columns = min(2, len(shown))
    rows = -(-len(shown) // columns)
    fig, axes = plt.subplots(
        rows, columns, figsize=(5.6 * columns, 3.4 * rows + 0.5), squeeze=False, layout="constrained"
    )
    for ax, c in zip(axes.flat, shown):
        rec, sim = s.recorded[c.channel], s.simulated[c.channel]
        ax.fill_between(s.t, rec - c.band, rec + c.band, color="0.85", lw=0, label="band about the recording", zorder=1)
        colour = "tab:red" if not c.passed else "tab:blue"
        ax.plot(s.t, sim, color=colour, lw=1.4, alpha=0.85, label="simulated", zorder=2)
        ax.plot(s.t, rec, color="0.1", lw=0.8, label="recorded", zorder=3)  # on top: never hidden
        verdict = "pass" if c.passed else "FAIL"
        where = _decided_at(s.t, rec, sim)
        ax.set_title(
            f"{c.standard} {CHANNELS[c.channel][1]} ({c.simulated_by}): max |error| {c.max_error:.3g} pu, "
            f"band ±{c.band:.3g} pu: {verdict}",
            fontsize=9,
        )
        if where is not None and s.t[-1] - s.t[0] > 3 * ZOOM_S:
            # a step's failing 40-90 ms cannot be seen in a 48 s window: shown where it is decided
            ax.set_xlim(max(s.t[0], where - ZOOM_S), min(s.t[-1], where + ZOOM_S))
            ax.autoscale_view(scalex=False)
            _fit_y(ax, s.t, rec, sim, c.band)
        ax.set_xlabel("t (s)" if where is None else f"t (s), around the largest error at {where:.2f} s")
        ax.set_ylabel(UNITS.get(c.channel, c.channel))
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(shown) :]:
        ax.set_visible(False)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=3, fontsize=8)  # off the traces
    return fig


def _decided_at(t: Any, rec: Any, sim: Any) -> float | None:
    """Where the check is decided: the time of the largest |simulated - recorded| (None: no finite one)."""
    import numpy as np

    gap = np.abs(np.asarray(sim, float) - np.asarray(rec, float))
    if not np.isfinite(gap).any():
        return None
    return float(t[int(np.nanargmax(gap))])


def _fit_y(ax: Any, t: Any, rec: Any, sim: Any, band: float) -> None:
    """The y axis to what the zoomed window shows (the band included)."""
    import numpy as np

    lo, hi = ax.get_xlim()
    inside = (t >= lo) & (t <= hi)
    values = np.concatenate(
        [np.asarray(rec, float)[inside] + d for d in (-band, band)] + [np.asarray(sim, float)[inside]]
    )
    values = values[np.isfinite(values)]
    if values.size:
        pad = 0.05 * max(float(np.ptp(values)), 1e-6)
        ax.set_ylim(float(values.min()) - pad, float(values.max()) + pad)


def overlays_html(result: UnitValidation) -> str:
    """Each checked event's overlay (recorded, simulated, the band) with its notes, as HTML."""
    return "".join(
        f"<h3>{html.escape(s.scenario)} ({html.escape(s.kind)})</h3>"
        + f'<img src="{png_data_uri(overlay_figure(s))}" alt="{html.escape(s.scenario)}">'
        + "".join(f"<p class=note>{html.escape(n)}</p>" for n in s.notes)
        for s in result.scenarios
        if s.checks
    )


def write_report(path: str | Path, result: UnitValidation, source: str) -> Path:
    figure_backend()
    rows = check_rows(result)
    figures = overlays_html(result)
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in result.notes) or "<li>none</li>"
    tol = result.as_json()["tolerances"]
    doc = f"""<!doctype html><html><head><meta charset="utf-8"><title>phid validate: {html.escape(source)}</title>
<style>{STYLE}</style></head><body>
<h1>MOD-026/027 validation</h1>
<p>Unit: <code>{html.escape(result.unit)}</code> &middot; recording: <code>{html.escape(source)}</code></p>
<p>MOD-026 (excitation: Q, E_fd): <b>{html.escape(verdict_text(result, "MOD-026"))}</b> &middot;
MOD-027 (turbine-governor: P, P_m): <b>{html.escape(verdict_text(result, "MOD-027"))}</b></p>
<p>{html.escape(method_text(result))} {html.escape(why_larger_than_identify(result))}
Bands: P, Q {html.escape(tol["p_e, q_e"])}; E_fd, P_m
{html.escape(tol["v_f, p_m"])}.</p>
{html_table(CHECK_HEADERS, rows, text_columns=(0, 1))}
<h2>Notes</h2><ul>{notes}</ul>
<h2>Recorded against simulated</h2>
{figures}
</body></html>"""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_text(p, doc)
    return p
