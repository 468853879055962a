"""The diagnosis as one self-contained HTML page: tables, worst scenarios before/after, residual spectra."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np

from phid_ros.cli.report import STYLE, png_data_uri
from phid_ros.diagnose.fit import evaluate
from phid_ros.diagnose.playin import OUTPUTS, PlayIn
from phid_ros.diagnose.workflow import Diagnosis
from phid_ros.io.outputs import write_text
from phid_ros.model.parameters import PARAMETER_NAMES

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

    fig, axes = plt.subplots(len(SHOWN), len(worst), figsize=(5.2 * len(worst), 2.3 * len(SHOWN)), squeeze=False)
    for col, j in enumerate(worst):
        b, a = before[j], after[j]
        t = b.t - b.scenario.k_event * b.scenario.dt
        for row, c in enumerate(SHOWN):
            ax = axes[row][col]
            ax.plot(t, b.meas[c][:, 0], color="0.6", lw=0.6, label="measured")
            ax.plot(t, b.sim[c][:, 0], color="tab:red", lw=0.9, label="before")
            ax.plot(t, a.sim[c][:, 0], color="tab:blue", lw=0.9, ls="--", label="after")
            ax.set_ylabel(c)
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(b.scenario.name, fontsize=9)
        axes[-1][col].set_xlabel("time after the event (s)")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("Worst held-out scenarios: measured vs model before and after adding the named effects")
    fig.tight_layout()
    return png_data_uri(fig)


def _spectra(before: list[PlayIn], after: list[PlayIn], sigma: dict[str, float]) -> str:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(12, 6))
    for ax, c in zip(axes.ravel(), OUTPUTS):
        for runs, label, color in ((before, "before", "tab:red"), (after, "after", "tab:blue")):
            n = min(len(r.t) for r in runs)
            h = float(runs[0].t[1] - runs[0].t[0])
            spec = np.mean(
                [np.abs(np.fft.rfft((r.sim[c][:n, 0] - r.meas[c][:n, 0]) / sigma[c])) ** 2 / n for r in runs], axis=0
            )
            f = np.fft.rfftfreq(n, h)
            ax.loglog(f[1:], spec[1:], lw=0.8, color=color, label=label)
        ax.axhline(1.0, color="0.5", lw=0.6, ls=":")
        ax.set_title(c, fontsize=9)
        ax.grid(alpha=0.3, which="both")
    axes[0][0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("Hz")
    fig.suptitle("Residual spectra on the held-out scenarios (in units of sensor-noise power; 1 = white noise)")
    fig.tight_layout()
    return png_data_uri(fig)


def write_report(path: str | Path, d: Diagnosis, doc: dict[str, Any], source: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    before, after = _runs(d)
    worst = _worst(before, d.sigma)
    eff_rows = (
        "".join(
            f"<tr><td>{html.escape(e['name'])}</td><td>{html.escape(_values(e['parameters']))}</td>"
            f"<td>{e['rmse_before']:.3g}</td><td>{e['rmse_after']:.3g}</td><td>{e['delta_bic']:+.0f}</td>"
            f"<td>{html.escape(e['signature'])}</td></tr>"
            for e in doc["effects"]
        )
        or '<tr><td colspan="6">nothing is missing</td></tr>'
    )
    ch_rows = "".join(
        f"<tr><td>{c}</td><td>{v['rmse_before']:.3g}</td><td>{v['rmse_after']:.3g}</td>"
        f"<td>{v['unexplained_before']:.3g}</td><td>{v['unexplained_after']:.3g}</td></tr>"
        for c, v in doc["channels"].items()
    )
    truth = doc.get("truth")
    p_rows = "".join(
        f"<tr><td>{n}</td><td>{doc['parameters_identified'][n]:.4g}</td><td>{doc['parameters_base_refit'][n]:.4g}</td>"
        f"<td><b>{doc['parameters'][n]:.4g}</b></td>"
        + (
            f"<td>{truth[n]:.4g}</td><td>{doc['errors_pct']['identified'][n]:+.2f} %</td>"
            f"<td>{doc['errors_pct']['after'][n]:+.2f} %</td>"
            if truth
            else ""
        )
        + "</tr>"
        for n in PARAMETER_NAMES
    )
    t_rows = "".join(
        f"<tr><td>{i}</td><td>{html.escape(t['candidate'])}</td>"
        f"<td>{'-' if t['delta_bic'] is None else format(t['delta_bic'], '+.0f')}</td>"
        f"<td>{'-' if t['heldout_gain'] is None else format(-100 * t['heldout_gain'], '+.0f') + ' %'}</td>"
        f"<td>{'named' if t['accepted'] else ''}</td><td>{html.escape(_values(t['parameters'] or {}))}</td></tr>"
        for i, r in enumerate(doc["rounds"], start=1)
        for t in r["trials"]
    )
    gap = doc.get("gap_before")
    gap_html = ""
    if gap:
        parts = []
        for part in ("by_kind", "by_phase", "by_channel", "by_band"):
            items = sorted(gap[part].items(), key=lambda kv: -kv[1])
            parts.append(
                f"<tr><td>{part[3:]}</td><td>"
                + ", ".join(f"{html.escape(k)}: {v:.3g}" for k, v in items)
                + "</td></tr>"
            )
        gap_html = (
            "<h2>Where the identified fourth-order model and the measurement disagree</h2>"
            "<p>Unexplained residual power (noise variances) of the three-stage model, all scenarios.</p>"
            f"<table>{''.join(parts)}</table>"
        )
    problems = "".join(f"<li>{html.escape(p)}</li>" for p in doc["problems"]) or "<li>none</li>"
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>phid diagnose: {html.escape(source)}</title>
<style>{STYLE}</style></head><body>
<h1>Missing-physics diagnosis</h1>
<p>Input: <code>{html.escape(source)}</code> &middot; fit on {", ".join(map(html.escape, doc["fit_scenarios"]))}
&middot; held out: {", ".join(map(html.escape, doc["heldout_scenarios"]))}</p>
<h2>Named effects</h2>
<table><tr><th>effect</th><th>fitted parameters</th><th>RMSE before</th><th>RMSE after</th><th>ΔBIC</th>
<th>signature</th></tr>{eff_rows}</table>
<p>Overall held-out RMSE {doc["rmse_before"]:.3g} &rarr; <b>{doc["rmse_after"]:.3g}</b>.
{html.escape(doc["rmse_definition"])}</p>
<h2>Per channel (held-out)</h2>
<table><tr><th>channel</th><th>RMSE before</th><th>RMSE after</th><th>unexplained before</th>
<th>unexplained after</th></tr>{ch_rows}</table>
<h2>Base parameters</h2>
<table><tr><th>parameter</th><th>identified</th><th>4th-order refit</th><th>after</th>
{"<th>truth</th><th>err identified</th><th>err after</th>" if truth else ""}</tr>{p_rows}</table>
<h2>Candidates</h2>
<table><tr><th>round</th><th>candidate</th><th>ΔBIC</th><th>held-out change</th><th></th><th>fitted values</th></tr>
{t_rows}</table>
{gap_html}
<h2>Notes</h2><ul>{problems}</ul>
<img src="{_traces(before, after, worst)}" alt="worst scenarios before and after">
<img src="{_spectra(before, after, d.sigma)}" alt="residual spectra">
</body></html>"""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text(out, page)
    return out


def _values(values: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in values.items())
