"""One self-contained HTML report: tables plus the paper's kinds of figures (PNG, inlined)."""

from __future__ import annotations

import base64
import html
import io
import math
from pathlib import Path

import numpy as np

from phid_ros.ident.pipeline import IdentificationResult
from phid_ros.ident.validation import play_in
from phid_ros.io.outputs import write_text
from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME, GeneratorParameters, validation_problems

STYLE = (
    "body{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}"
    "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}"
    "td:first-child,th:first-child{text-align:left}img{max-width:100%}"
)


def png_data_uri(fig: object) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")  # type: ignore[attr-defined]
    import matplotlib.pyplot as plt

    plt.close(fig)  # type: ignore[arg-type]
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _scenario_figure(res: IdentificationResult) -> str | None:
    """Figure 1 of the paper: the fault scenarios' signals."""
    import matplotlib.pyplot as plt

    faults = [s for s in res.scenarios if s.kind == "fault" and s.role == "identify"]
    if not faults:
        return None
    fig, axes = plt.subplots(5, 1, figsize=(9, 11), sharex=True)
    for s in faults:
        k0 = max(0, s.k_event - int(0.5 / s.dt))
        k1 = min(s.n, s.k_event + int(5.0 / s.dt))
        t = (np.arange(k0, k1) - s.k_event) * s.dt
        label = s.name
        axes[0].plot(t, np.hypot(s["i_d"], s["i_q"])[k0:k1], lw=0.8, label=label)
        axes[1].plot(t, s["v_t"][k0:k1], lw=0.8)
        axes[2].plot(t, s["omega"][k0:k1] - 1.0, lw=0.8)
        axes[3].plot(t, s["i_d"][k0:k1], lw=0.8)
        axes[4].plot(t, s["i_q"][k0:k1], lw=0.8)
    for ax, lab in zip(axes, ("I (pu)", "V_t (pu)", "Δω (pu)", "I_d (pu)", "I_q (pu)")):
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel("time after fault inception (s)")
    fig.suptitle("Fault scenarios: measured signals (cf. paper Fig. 1)")
    return png_data_uri(fig)


def _validation_figures(res: IdentificationResult, truth: GeneratorParameters | None) -> list[tuple[str, str]]:
    """Figures 4-6: rotor angle and speed of identified, reference and IEEE 115 models."""
    import matplotlib.pyplot as plt

    model = res.complete()
    if model is None:
        return []
    chosen = [s for s in res.scenarios if s.role == "validate"] or res.scenarios[:3]
    sets: list[tuple[str, GeneratorParameters]] = [("proposed", model)]
    if truth is not None:
        sets.append(("reference", truth))
    base = {n: e.value for n, e in res.baseline.items()}
    if (
        len(base) == len(PARAMETER_NAMES)
        and all(math.isfinite(v) for v in base.values())
        and not validation_problems(base)
    ):
        sets.append(("IEEE 115", GeneratorParameters(**base)))
    trajs = play_in(chosen, [p for _, p in sets])
    out = []
    styles = {
        "proposed": dict(ls="-.", color="#d8a200"),
        "reference": dict(ls="-", color="#1f5fbf"),
        "IEEE 115": dict(ls="--", color="#c0392b"),
    }
    for s, tr in zip(chosen, trajs):
        fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
        idx = np.arange(0, s.n, max(1, int(round((tr.t[1] - tr.t[0]) / s.dt))))[: len(tr.t)]
        axes[0].plot(tr.t, np.degrees(s["delta"][idx]), color="0.6", lw=0.6, label="measured")
        axes[1].plot(tr.t, s["omega"][idx], color="0.6", lw=0.6, label="measured")
        for j, (name, _) in enumerate(sets):
            axes[0].plot(tr.t, np.degrees(tr.delta[:, j]), lw=1.2, label=name, **styles[name])
            axes[1].plot(tr.t, tr.omega[:, j], lw=1.2, label=name, **styles[name])
        axes[0].set_ylabel("δ (deg)")
        axes[1].set_ylabel("ω (pu)")
        axes[1].set_xlabel("time (s)")
        for ax in axes:
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=8)
        fig.suptitle(f"Validation: {s.name} (cf. paper Figs. 4-6)")
        out.append((s.name, png_data_uri(fig)))
    return out


def _cell(v: float, digits: int = 5) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.{digits}g}"


def write_report(path: str | Path, res: IdentificationResult, truth: GeneratorParameters | None, source: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    t = truth.as_dict() if truth else {}
    rows = []
    for n in PARAMETER_NAMES:
        e = res.estimates.get(n)
        b = res.baseline.get(n)
        v = e.value if e else math.nan
        err = f"{100 * (v / t[n] - 1):+.2f} %" if truth and math.isfinite(v) else ""
        berr = f"{100 * (b.value / t[n] - 1):+.2f} %" if truth and b and math.isfinite(b.value) else ""
        rows.append(
            f"<tr><td>{html.escape(n)}</td><td>{SPECS_BY_NAME[n].unit}</td>"
            f"<td>{_cell(b.value if b else math.nan, 4)}{' (bound)' if b and b.at_bound else ''}</td><td>{berr}</td>"
            f"<td><b>{_cell(v)}</b></td><td>{_cell(e.std if e else math.nan, 2)}</td><td>{err}</td>"
            f"<td>{_cell(t.get(n, math.nan), 4)}</td>"
            f"<td>{html.escape(', '.join(e.drivers) if e else '')}</td>"
            f"<td>{'' if e is None or e.identifiable else 'not identified'}</td></tr>"
        )
    vrows = []
    if res.validation:
        for m in res.validation.scenarios:
            vrows.append(
                f"<tr><td>{html.escape(m.scenario)}</td><td>{m.rms_delta_deg:.4f}</td><td>{m.max_delta_deg:.4f}</td>"
                f"<td>{m.rms_omega_pct:.5f}</td><td>{m.rmse:.2e}</td><td>{m.mae:.2e}</td><td>{m.std:.2e}</td>"
                f"<td>{m.max_dp:.4f}</td><td>{m.max_dq:.4f}</td><td>{'pass' if m.mod026_pass else 'FAIL'}</td></tr>"
            )
    figs = []
    f1 = _scenario_figure(res)
    if f1:
        figs.append(f'<h2>Scenario signals</h2><img src="{f1}" alt="fault scenario signals">')
    for name, img in _validation_figures(res, truth):
        figs.append(f'<h3>{html.escape(name)}</h3><img src="{img}" alt="validation {html.escape(name)}">')
    problems = "".join(f"<li>{html.escape(p)}</li>" for p in res.problems) or "<li>none</li>"
    against = res.validation.against if res.validation else "—"
    doc = f"""<!doctype html><html><head><meta charset="utf-8"><title>phid identify: {html.escape(source)}</title>
<style>{STYLE}</style></head><body>
<h1>Three-stage identification</h1>
<p>Input: <code>{html.escape(source)}</code> &middot; method: <b>{html.escape(res.method)}</b> &middot;
{len(res.scenarios)} scenarios</p>
<h2>Parameters</h2>
<table><tr><th>parameter</th><th>unit</th><th>IEEE 115</th><th>err</th><th>proposed</th><th>± std</th><th>err</th>
<th>truth</th><th>driven by</th><th></th></tr>{"".join(rows)}</table>
<h2>Validation against the {against}</h2>
<table><tr><th>scenario</th><th>RMS δ °</th><th>max δ °</th><th>RMS ω %</th><th>RMSE pu</th><th>MAE pu</th>
<th>STD pu</th><th>max ΔP</th><th>max ΔQ</th><th>MOD-026</th></tr>{"".join(vrows)}</table>
<h2>Notes</h2><ul>{problems}</ul>
{"".join(figs)}
</body></html>"""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_text(p, doc)
    return p
