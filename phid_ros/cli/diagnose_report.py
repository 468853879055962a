"""The diagnosis as one self-contained HTML page: tables, worst scenarios before/after, residual spectra."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np

from phid_ros.cli.common import figure_backend, log_ticks
from phid_ros.cli.html import STYLE, html_table, png_data_uri
from phid_ros.cli.tables import CHANNEL_LABELS, axis_label, effect_values_text, fmt, pct, signed_int
from phid_ros.diagnose.fit import evaluate
from phid_ros.diagnose.outcome import Diagnosis
from phid_ros.diagnose.results import is_determined
from phid_ros.ident.plant_playin import OUTPUTS, PlayIn
from phid_ros.io.files.outputs import write_text
from phid_ros.model.parameters import PARAMETER_NAMES, SYMBOLS

SHOWN = ("omega", "delta", "i_d", "q_e")


def _runs(d: Diagnosis) -> tuple[list[PlayIn], list[PlayIn]]:
    before = evaluate(d.heldout_windows, d.sigma, d.base_fit.model)
    after = evaluate(d.heldout_windows, d.sigma, d.final.model)
    return before, after


def _worst(before: list[PlayIn], sigma: dict[str, float], k: int = 2) -> list[int]:
    err = [sum(float(np.mean(((r.sim[c] - r.meas[c]) / sigma[c]) ** 2)) for c in OUTPUTS) for r in before]
    return list(np.argsort(err)[::-1][:k])


def _traces(before: list[PlayIn], after: list[PlayIn], worst: list[int]) -> str:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(
        len(SHOWN), len(worst), figsize=(5.2 * len(worst), 2.3 * len(SHOWN)), squeeze=False, layout="constrained"
    )
    for col, j in enumerate(worst):
        b, a = before[j], after[j]
        t = b.t - b.scenario.k_event * b.scenario.dt
        for row, c in enumerate(SHOWN):
            ax = axes[row][col]
            ax.plot(t, b.meas[c][:, 0], color="0.6", lw=0.6, label="measured")
            ax.plot(t, b.sim[c][:, 0], color="tab:red", lw=0.9, label="before")
            ax.plot(t, a.sim[c][:, 0], color="tab:blue", lw=0.9, ls="--", label="after")
            ax.set_ylabel(axis_label(c))
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(b.scenario.name, fontsize=9)
        axes[-1][col].set_xlabel("time after the event (s)")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("Worst held-out scenarios: measured vs model before and after adding the named effects")
    return png_data_uri(fig)


def _spectra(before: list[PlayIn], after: list[PlayIn], sigma: dict[str, float]) -> str:
    """Welch spectra of the held-out residuals in units of the sensor noise: white noise sits at 1."""
    import matplotlib.pyplot as plt
    from scipy.signal import welch

    fig, axes = plt.subplots(2, 3, figsize=(12, 6), layout="constrained")
    for ax, c in zip(axes.ravel(), OUTPUTS):
        for runs, label, color in ((before, "before", "tab:red"), (after, "after", "tab:blue")):
            h = float(runs[0].t[1] - runs[0].t[0])
            n = min(len(r.t) for r in runs)
            seg = min(n, 1024)
            psd = []
            for r in runs:
                f, p = welch((r.sim[c][:n, 0] - r.meas[c][:n, 0]) / sigma[c], fs=1.0 / h, nperseg=seg)
                psd.append(p)
            # one-sided density of unit-variance white noise is 2/fs: scale so that it reads 1
            ax.loglog(f[1:], np.mean(psd, axis=0)[1:] / (2.0 * h), lw=1.0, color=color, label=label)
        ax.axhline(1.0, color="0.3", lw=1.0, ls="--", label="sensor-noise floor")
        symbol, unit = CHANNEL_LABELS[c]
        ax.set_title(f"{symbol} residual", fontsize=9)
        ax.grid(alpha=0.3, which="both")
        log_ticks(ax)
    axes[0][0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("frequency (Hz)")
    for ax in axes[:, 0]:
        ax.set_ylabel("power / noise power")
    fig.suptitle("Residual spectra on the held-out scenarios (Welch; 1 = the sensors' white noise)")
    return png_data_uri(fig)


def _effects_table(doc: dict[str, Any]) -> str:
    return html_table(
        ["effect", "fitted parameters", "held-out RMSE before (σ)", "held-out RMSE after (σ)", "ΔBIC", "signature"],
        [
            [
                e["name"],
                effect_values_text(e["parameters"], e, nd=" (not determined by these data)"),
                fmt(e["rmse_before"], 3),
                fmt(e["rmse_after"], 3),
                signed_int(e["delta_bic"]),
                e["signature"],
            ]
            for e in doc["effects"]
        ]
        or [["nothing is missing", "", "", "", "", ""]],
        text_columns=(1, 5),
    )


def _channels_table(doc: dict[str, Any]) -> str:
    return html_table(
        ["channel", "unit", "RMSE before", "RMSE after", "unexplained before", "unexplained after"],
        [
            [
                *CHANNEL_LABELS[c],
                fmt(v["rmse_before"], 3),
                fmt(v["rmse_after"], 3),
                fmt(v["unexplained_before"], 3),
                fmt(v["unexplained_after"], 3),
            ]
            for c, v in doc["channels"].items()
        ],
    )


def _trials_table(doc: dict[str, Any]) -> str:
    return html_table(
        ["round", "candidate", "ΔBIC", "held-out change", "named", "fitted values"],
        [
            [
                str(i),
                t["candidate"],
                "-" if t["delta_bic"] is None else signed_int(t["delta_bic"]),
                "-" if t["heldout_gain"] is None else pct(-100 * t["heldout_gain"], 0),
                "yes" if t["accepted"] else "",
                effect_values_text(t["parameters"] or {}),
            ]
            for i, r in enumerate(doc["rounds"], start=1)
            for t in r["trials"]
        ],
        text_columns=(5,),
    )


def _parameters_table(doc: dict[str, Any]) -> str:
    truth = doc.get("truth")
    p_head = ["parameter", "identified", "4th-order refit", "after"]
    p_head += ["truth", "err identified", "err after"] if truth else []
    p_rows = []
    for n in PARAMETER_NAMES:
        row = [
            SYMBOLS[n],
            fmt(doc["parameters_identified"][n])
            + (" (at its search bound)" if n in doc.get("parameters_identified_at_bound", ()) else ""),
            fmt(doc["parameters_base_refit"][n]),
            fmt(doc["parameters"][n]) + ("" if is_determined(doc, n) else " (not determined by these data)"),
        ]
        if truth:
            row += [fmt(truth[n]), pct(doc["errors_pct"]["identified"][n]), pct(doc["errors_pct"]["after"][n])]
        p_rows.append(row)
    return html_table(p_head, p_rows)


def _gap_section(doc: dict[str, Any]) -> str:
    gap = doc.get("gap_before")
    if not gap:
        return ""
    rows = [
        [part[3:], ", ".join(f"{k}: {fmt(v, 3)}" for k, v in sorted(gap[part].items(), key=lambda kv: -kv[1]))]
        for part in ("by_kind", "by_phase", "by_channel", "by_band")
    ]
    return (
        "<h2>Where the identified fourth-order model and the measurement disagree</h2>"
        "<p>Unexplained residual power of the three-stage model over all scenarios, in sensor-noise "
        "variances, largest first.</p>"
        + html_table(["split by", "unexplained power (noise variances)"], rows, text_columns=(1,))
    )


def write_report(path: str | Path, d: Diagnosis, doc: dict[str, Any], source: str) -> Path:
    figure_backend()
    before, after = _runs(d)
    worst = _worst(before, d.sigma)
    problems = "".join(f"<li>{html.escape(p)}</li>" for p in doc["problems"]) or "<li>none</li>"
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>phid diagnose: {html.escape(source)}</title>
<style>{STYLE}</style></head><body>
<h1>Missing-physics diagnosis</h1>
<p>Input: <code>{html.escape(source)}</code> &middot; fit on {", ".join(map(html.escape, doc["fit_scenarios"]))}
&middot; held out: {", ".join(map(html.escape, doc["heldout_scenarios"]))}</p>
<h2>Named effects</h2>
{_effects_table(doc)}
<p>Overall held-out RMSE, in units of the sensor noise σ: {doc["rmse_before"]:.3g} &rarr;
<b>{doc["rmse_after"]:.3g}</b>. {html.escape(doc["rmse_definition"])}</p>
<h2>Per channel (held-out)</h2>
{_channels_table(doc)}
<h2>Base parameters</h2>
{_parameters_table(doc)}
<h2>Candidates</h2>
{_trials_table(doc)}
{_gap_section(doc)}
<h2>Notes</h2><ul>{problems}</ul>
<h2>Worst held-out scenarios</h2>
<img src="{_traces(before, after, worst)}" alt="worst scenarios before and after">
<h2>Residual spectra</h2>
<img src="{_spectra(before, after, d.sigma)}" alt="residual spectra">
</body></html>"""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text(out, page)
    return out
