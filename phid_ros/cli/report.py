"""One self-contained HTML report: tables plus the paper's kinds of figures (PNG, inlined)."""

from __future__ import annotations

import html
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from phid_ros.cli.common import figure_backend
from phid_ros.cli.html import STYLE, html_table, png_data_uri
from phid_ros.cli.tables import pct, withheld_text
from phid_ros.controls.fit import ControlFit
from phid_ros.controls.unit_validation import UnitValidation
from phid_ros.day_summary import HEADERS, day_summary
from phid_ros.ident.pipeline import IdentificationResult
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import KINDS as KIND_ORDER
from phid_ros.ident.validation import play_in
from phid_ros.io.files.outputs import write_text
from phid_ros.model.parameters import (
    PARAMETER_NAMES,
    SPECS_BY_NAME,
    SYMBOLS,
    GeneratorParameters,
    validation_problems,
)

SIGNALS = (
    ("v_t", "V_t (pu)"),
    ("omega", "Δω (pu)"),
    ("p_e", "P_e (pu)"),
    ("q_e", "Q_e (pu)"),
    ("i_d", "I_d (pu)"),
    ("i_q", "I_q (pu)"),
)


def _scenario_figure(res: IdentificationResult) -> str | None:
    """Figure 1 of the paper, for every kind of identification scenario (one column per kind)."""
    import matplotlib.pyplot as plt

    used = [s for s in res.scenarios if s.role == "identify"]
    kinds = sorted(
        {s.kind for s in used},
        key=lambda k: KIND_ORDER.index(k) if k in KIND_ORDER else 9,
    )
    # a channel no scenario recorded (a recorder's day: no speed, no I_d, I_q) is not drawn as an
    # empty axis; the caption names what was left out
    signals = [(n, label) for n, label in SIGNALS if any(s.has(n) for s in used)]
    if not kinds or not signals:
        return None
    fig, axes = plt.subplots(
        len(signals),
        len(kinds),
        figsize=(4.2 * len(kinds) + 1, 1.6 * len(signals) + 1.4),
        sharex="col",
        squeeze=False,
        layout="constrained",
    )
    for col, kind in enumerate(kinds):
        for s in (s for s in used if s.kind == kind):
            k0 = max(0, s.k_event - int(0.5 / s.dt))
            k1 = min(s.n, s.k_event + int(5.0 / s.dt))
            t = (np.arange(k0, k1) - s.k_event) * s.dt
            for row, (name, _) in enumerate(signals):
                if s.has(name):
                    x = s[name][k0:k1] - (1.0 if name == "omega" else 0.0)
                    axes[row][col].plot(t, x, lw=0.8, label=s.name)
        axes[0][col].set_title(kind.replace("_", " ") + " scenarios", fontsize=10)
        axes[0][col].legend(fontsize=6)
        axes[-1][col].set_xlabel("time after the event (s)")
    for row, (_, label) in enumerate(signals):
        axes[row][0].set_ylabel(label)
        for ax in axes[row]:
            ax.grid(alpha=0.3)
    missing = [label.split(" (")[0] for n, label in SIGNALS if (n, label) not in signals]
    left_out = f"; not recorded, not drawn: {', '.join(missing)}" if missing else ""
    fig.suptitle(f"Identification scenarios: measured signals (cf. paper Fig. 1){left_out}")
    return png_data_uri(fig)


VALIDATED = (
    ("delta", "δ (deg)", True),
    ("omega", "ω (pu)", False),
    ("p_e", "P_e (pu)", False),
    ("q_e", "Q_e (pu)", False),
)
# the identified model is the wide pale line underneath; the thin ones drawn over it stay visible
# where all agree (they do to a hair on a good fit, and a thick line on top hid the measurement)
STYLES = {
    "proposed": dict(ls="-", color="#f5a623", lw=3.2, zorder=2, alpha=0.75),
    "IEEE 115": dict(ls=":", color="#c0392b", lw=1.2, zorder=3),
    "reference": dict(ls="--", color="#1f5fbf", lw=1.1, zorder=4),
}
MEASURED_STYLE = dict(color="k", lw=0.7, zorder=5)


def _validation_figures(res: IdentificationResult, truth: GeneratorParameters | None) -> list[tuple[str, str]]:
    """Figures 4-6 extended: δ, ω, P and Q of each model against the measurement, residuals beneath.

    The proposed (identified) model is the wide pale line beneath the others; P and Q carry the
    MOD-026 ±0.05 pu band around the measurement.
    """
    import matplotlib.pyplot as plt

    from phid_ros.ident.validation import MOD026_TOLERANCE_PU, play_in_samples

    model = res.complete()
    if model is None:
        return []
    chosen = [s for s in res.scenarios if s.role == "validate"] or res.scenarios[:3]
    sets: list[tuple[str, GeneratorParameters]] = []
    if truth is not None:
        sets.append(("reference", truth))
    base = {n: e.value for n, e in res.baseline.items()}
    if (
        len(base) == len(PARAMETER_NAMES)
        and all(math.isfinite(v) for v in base.values())
        and not validation_problems(base)
    ):
        sets.append(("IEEE 115", GeneratorParameters(**base)))
    sets.append(("proposed", model))
    trajs = play_in(chosen, [p for _, p in sets])
    out = []
    for s, tr in zip(chosen, trajs):
        fig, axes = plt.subplots(
            2 * len(VALIDATED),
            1,
            figsize=(9, 13),
            sharex=True,
            layout="constrained",
            gridspec_kw={"height_ratios": [3, 1] * len(VALIDATED)},
        )
        idx = play_in_samples(s)[: len(tr.t)]
        t = tr.t - s.k_event * s.dt
        for i, (name, label, degrees) in enumerate(VALIDATED):
            ax, rax = axes[2 * i], axes[2 * i + 1]
            scale = np.degrees if degrees else (lambda x: x)  # noqa: E731
            meas = scale(s[name][idx])
            if name in ("p_e", "q_e"):
                ax.fill_between(
                    t,
                    meas - MOD026_TOLERANCE_PU,
                    meas + MOD026_TOLERANCE_PU,
                    color="0.85",
                    lw=0,
                    label="MOD-026 ±0.05 pu",
                )
                rax.axhspan(-MOD026_TOLERANCE_PU, MOD026_TOLERANCE_PU, color="0.88", lw=0)
            ax.plot(t, meas, label="measured", **MEASURED_STYLE)
            for j, (set_name, _) in enumerate(sets):
                sim = scale(getattr(tr, name)[:, j])
                ax.plot(t, sim, label=set_name, **STYLES[set_name])
                rax.plot(t, sim - meas, **STYLES[set_name])
            ax.set_ylabel(label)
            rax.set_ylabel("model −\nmeasured", fontsize=8)
            for a in (ax, rax):
                a.grid(alpha=0.3)
        axes[0].legend(fontsize=8, ncol=5, loc="best")
        axes[-1].set_xlabel("time after the event (s)")
        fig.suptitle("Each model against the measurement (cf. paper Figs. 4-6); its residual beneath each signal")
        out.append((s.name, png_data_uri(fig)))
    return out


def _cell(v: float, digits: int = 5) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.{digits}g}"


def _note(e: Estimate | None) -> str:
    """What the reader may do with the value: use it, or not and why, and its estimator's own remark."""
    if e is None:
        return "not estimated"
    said = "identified" if e.identifiable else "withheld: not identifiable from these data"
    if e.at_bound:
        said += "; at its search bound"
    return f"{said}; {e.note}" if e.note else said


def _parameter_table(res: IdentificationResult, truth: GeneratorParameters | None) -> str:
    """Table 7's layout: IEEE 115 | proposed ± std | truth and errors, what drove each, and flags."""
    t = truth.as_dict() if truth else {}
    published = res.published()
    rows = []
    for n in PARAMETER_NAMES:
        e = res.estimates.get(n)
        b = res.baseline.get(n)
        v = e.value if e and n in published else math.nan
        row = [SYMBOLS[n], SPECS_BY_NAME[n].unit]
        if res.baseline:
            row.append(_cell(b.value if b else math.nan, 4) + (" (bound)" if b and b.at_bound else ""))
            if truth:
                row.append(pct(100 * (b.value / t[n] - 1)) if b and math.isfinite(b.value) else "")
        withheld = e is not None and n not in published
        shown = withheld_text(e) if e is not None and withheld else _cell(v)
        row += [shown, _cell(e.std if e and not withheld else math.nan, 2)]
        if truth:
            row += [pct(100 * (v / t[n] - 1)) if math.isfinite(v) else "", _cell(t[n], 4)]
        row += [", ".join(e.drivers) if e else "", _note(e)]
        rows.append(row)
    head = ["parameter", "unit"]
    if res.baseline:
        head += ["IEEE 115"] + (["err IEEE 115"] if truth else [])
    head += ["proposed", "± std"] + (["err proposed", "truth"] if truth else []) + ["driven by", "note"]
    return html_table(head, rows, text_columns=(len(head) - 2,))


def _validation_table(res: IdentificationResult) -> str:
    """Tables 8-9 per scenario, and the MOD-026 check."""
    vrows = [
        [
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
        ]
        for m in (res.validation.scenarios if res.validation else [])
    ]
    vhead = [
        "scenario",
        "RMS δ (°)",
        "max δ (°)",
        "RMS ω (%)",
        "RMSE (pu)",
        "MAE (pu)",
        "STD (pu)",
        "max ΔP (pu)",
        "max ΔQ (pu)",
        "MOD-026",
    ]
    return html_table(vhead, vrows)


def _validation_section(res: IdentificationResult) -> str:
    """The held-out validation (Tables 8-9), or why there is none: no empty table, no footnote on
    columns that are not there (a recorder's day is validated by its no-load playback instead)."""
    if res.validation is None or not res.validation.scenarios:
        why = next((p for p in res.problems if p.startswith("validation skipped")), "no validation scenario was played")
        return f"<h2>Validation</h2><p>Not run: {html.escape(why)}.</p>"
    return (
        f"<h2>Validation against the {html.escape(res.validation.against)}</h2>"
        + _validation_table(res)
        + "<p>RMSE, MAE and STD of the combined state-trajectory error (Table 9); MOD-026: simulated P and Q "
        "within ±0.05 pu of the measurement.</p>"
    )


def _controls_section(controls: Mapping[str, ControlFit | str]) -> str:
    """The exciter and governor as the terminal names them: the model, each constant (PSS/E's names)
    with its std and whether the data determine it, and the fit's errors; or why no model is named."""
    if not controls:
        return "<p>Not fitted (no control channel in the recording).</p>"
    parts = []
    for kind, fit in controls.items():
        if not isinstance(fit, ControlFit):
            parts.append(f"<h3>{html.escape(kind)}: none</h3><p>{html.escape(fit)}</p>")
            continue
        title = fit.model if fit.named else f"none named (best candidate {fit.model})"
        errors = f"fit RMSE {fit.fit_rmse:.2e} pu"
        if fit.heldout_rmse is not None:
            errors += f", held-out RMSE {fit.heldout_rmse:.2e} pu"
        if fit.none_heldout_rmse is not None:
            errors += f" (without any control action {fit.none_heldout_rmse:.2e} pu)"
        rows = [
            [
                n,
                "—" if v is None else f"{v:.5g}",
                _cell(fit.uncertainty.get(n) or math.nan, 2),
                "determined" if fit.identifiable.get(n) else "not determined by these data",
            ]
            for n, v in fit.parameters.items()
        ]
        table = html_table(["constant", "value", "± std", "note"], rows, text_columns=(3,)) if fit.named else ""
        parts.append(
            f"<h3>{html.escape(kind)}: {html.escape(title)}</h3><p>{html.escape(errors)}. {html.escape(fit.why)}</p>"
            + table
        )
    return "".join(parts)


def _day_section(res: IdentificationResult, controls: Mapping[str, ControlFit | str] | None) -> str:
    """What each test gave, where a recorder's channels were identified (its day's tests)."""
    if not res.determined_by:
        return ""
    rows = [r.cells() for r in day_summary(res, controls)]
    return f"<h2>What each test gave</h2>\n{html_table(HEADERS, rows, text_columns=(0, 2, 3, 4, 5))}"


def _no_load_section(result: UnitValidation) -> str:
    """The no-load tests played with the identified machine on open circuit (before any record):
    the checks as ``phid validate`` makes them and each event's overlay."""
    from phid_ros.cli.validate import CHECK_HEADERS, check_rows, overlays_html

    notes = "".join(f"<li>{html.escape(n)}</li>" for n in result.notes)
    return (
        "<h2>The no-load tests played with the identified machine</h2>"
        f"<p>{html.escape(result.unit)}</p><ul>{notes}</ul>"
        + html_table(CHECK_HEADERS, check_rows(result), text_columns=(0, 1))
        + overlays_html(result)
    )


def write_report(
    path: str | Path,
    res: IdentificationResult,
    truth: GeneratorParameters | None,
    source: str,
    controls: Mapping[str, ControlFit | str] | None = None,
    no_load: UnitValidation | None = None,
) -> Path:
    figure_backend()
    figs = []
    if no_load is not None:
        figs.append(_no_load_section(no_load))
    f1 = _scenario_figure(res)
    if f1:
        figs.append(f'<h2>Scenario signals</h2><img src="{f1}" alt="identification scenario signals">')
    for name, img in _validation_figures(res, truth):
        figs.append(f'<h3>Validation: {html.escape(name)}</h3><img src="{img}" alt="validation {html.escape(name)}">')
    problems = "".join(f"<li>{html.escape(p)}</li>" for p in res.problems) or "<li>none</li>"
    doc = f"""<!doctype html><html><head><meta charset="utf-8"><title>phid identify: {html.escape(source)}</title>
<style>{STYLE}</style></head><body>
<h1>Three-stage identification</h1>
<p>Input: <code>{html.escape(source)}</code> &middot; method: <b>{html.escape(res.method)}</b> &middot;
{len(res.scenarios)} scenarios</p>
<h2>Parameters</h2>
{_parameter_table(res, truth)}
<p>err = estimate / truth − 1. IEEE 115: the standard's test-based method (the paper's baseline);
"(bound)": at its search bound.</p>
<h2>Excitation and turbine-governor</h2>
{_controls_section(controls or {})}
{_day_section(res, controls)}
{_validation_section(res)}
<h2>Notes</h2><ul>{problems}</ul>
{"".join(figs)}
</body></html>"""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_text(p, doc)
    return p
