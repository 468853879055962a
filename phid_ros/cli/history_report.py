"""``phid history --report``: one unit's parameters over time, ±2σ bands, flagged changes marked."""

from __future__ import annotations

import html
import math
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np

from phid_ros.cli.common import figure_backend, mark_withheld
from phid_ros.cli.html import STYLE, html_table, png_data_uri
from phid_ros.cli.tables import CONCISE_LEGEND, estimate_text
from phid_ros.fleet.history import Change, Row, SisterGap
from phid_ros.io.files.outputs import write_text
from phid_ros.model.conventions import utc_of_stamp
from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME, SYMBOLS


def _when(ns: int | None) -> datetime | None:
    return None if ns is None else utc_of_stamp(ns)


def time_span(times: list[datetime]) -> tuple[datetime, datetime]:
    """The time axis's limits: the recordings' span and a twentieth either side, at least an hour (one
    recording alone spanned 2024-2028 by matplotlib's default date range)."""
    first, last = min(times), max(times)
    pad = max((last - first) / 20, timedelta(hours=1))
    return first - pad, last + pad


def _figure(rows: list[Row], flagged: list[Change]) -> str:
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r.status == "ok" and r.start_ns is not None]
    fig, axes = plt.subplots(4, 2, figsize=(10, 10), sharex=True)
    for ax, name in zip(axes.flat, PARAMETER_NAMES):
        t = [_when(r.start_ns) for r in ok]
        v = np.array([r.values.get(name, math.nan) for r in ok])
        s = np.array([r.stds.get(name, math.nan) for r in ok])
        good = np.array([r.well_identified(name) for r in ok], dtype=bool)
        # identified, but its std not computed (stage 3's X_d, X_q where stage 2 could not run): the
        # table prints the value, so the figure draws it, without a band
        bare = np.array([bool(r.identifiable.get(name)) for r in ok], dtype=bool) & np.isfinite(v) & ~good
        if good.any():
            tg = [x for x, g in zip(t, good) if g]
            ax.fill_between(tg, v[good] - 2 * s[good], v[good] + 2 * s[good], color="C0", alpha=0.25, label="±2σ")
            ax.plot(tg, v[good], "o-", color="C0", label="identified")
        if bare.any():
            tb = [x for x, b in zip(t, bare) if b]
            ax.plot(tb, v[bare], "o", mfc="none", mec="C0", label="identified, std not computed")
        mark_withheld(ax, [x for x, g, b in zip(t, good, bare) if not g and not b])
        if not (good.any() or bare.any()):
            # nothing to scale the value axis by: say so where the values would be
            ax.set_yticks([])
            ax.text(
                0.5,
                0.5,
                "withheld in every recording\n(not identifiable from these data)",
                ha="center",
                va="center",
                transform=ax.transAxes,
                color="0.35",
                fontsize=9,
            )
        for c in flagged:
            if c.parameter == name:
                ax.plot([_when(c.after.start_ns)], [c.after.values[name]], "o", ms=12, mfc="none", mec="red", mew=2)
                ax.annotate(
                    f"{c.relative:+.1%}",
                    (_when(c.after.start_ns), c.after.values[name]),
                    color="red",
                    textcoords="offset points",
                    xytext=(6, 6),
                )
        unit = SPECS_BY_NAME[name].unit
        ax.set_ylabel(f"{SYMBOLS[name]} ({unit})" if unit else SYMBOLS[name])
        ax.ticklabel_format(axis="y", useOffset=False)  # "+2.41" above an axis reads as a value
        ax.grid(alpha=0.3)
    handles: dict[str, Any] = {}
    for ax in axes.flat:  # one legend for every kind of mark drawn in any panel
        for h, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, h)
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=len(handles), fontsize=8)
    times = [w for r in ok if (w := _when(r.start_ns)) is not None]
    if times:
        axes.flat[0].set_xlim(*time_span(times))
    fig.autofmt_xdate()
    fig.suptitle("identified parameters per recording (red ring: change beyond the threshold)")
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    return png_data_uri(fig)


def _record_figure(rows: list[Row]) -> str:
    """The record on file's error per channel at each event, as a fraction of its band (1: the
    band's edge), over the events' times: a record going stale climbs toward the line."""
    import matplotlib.pyplot as plt

    by_channel: dict[str, list[tuple[datetime, float, bool]]] = {}
    for r in rows:
        for v in r.verdicts:
            when = _when(v.get("event_ns"))
            if when is None:
                continue
            for c in v["checks"]:
                ratio = c["max_error"] / c["band"] if c["band"] > 0 else math.nan
                by_channel.setdefault(f"{c['channel']} ({c['standard']})", []).append((when, ratio, c["passed"]))
    fig, ax = plt.subplots(figsize=(10, 3.6))
    ax_: Any = ax  # matplotlib's stubs take no datetime axis
    for k, (channel, points) in enumerate(sorted(by_channel.items())):
        points.sort(key=lambda p: p[0])
        t = [p[0] for p in points]
        ax_.plot(t, [p[1] for p in points], "o-", color=f"C{k}", label=channel, ms=4)
        bad = [p for p in points if not p[2]]
        if bad:
            ax_.plot([p[0] for p in bad], [p[1] for p in bad], "x", color="red", ms=9, mew=2)
    ax.axhline(1.0, color="red", lw=1, ls="--", label="band")
    ax.set_ylabel("max |error| / band")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    times = [p[0] for points in by_channel.values() for p in points]
    if times:
        ax_.set_xlim(*time_span(times))
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.25), ncol=4, fontsize=8)
    fig.autofmt_xdate()
    fig.suptitle("the record on file at each event (red cross: a check failed)")
    fig.tight_layout()
    return png_data_uri(fig)


def verdict_rows(rows: list[Row]) -> list[list[str]]:
    """One line per event played into the record on file: when, what, how many checks passed,
    the worst check (its error against its band)."""
    out = []
    for r in rows:
        for v in r.verdicts:
            checks = v["checks"]
            worst = max(checks, key=lambda c: c["max_error"] / c["band"] if c["band"] > 0 else math.inf)
            ratio = worst["max_error"] / worst["band"] if worst["band"] > 0 else math.inf
            when = v.get("event_ns")
            out.append(
                [
                    utc_of_stamp(when).strftime("%Y-%m-%d %H:%M:%S") if when is not None else "—",
                    v["scenario"],
                    f"{sum(c['passed'] for c in checks)} of {len(checks)}",
                    f"{worst['channel']} ({worst['standard']})",
                    f"{ratio:.3f}",
                    "pass" if v["passed"] else "FAIL",
                ]
            )
    return out


def _record_section(rows: list[Row]) -> str:
    records = sorted({Path(r.record).name for r in rows if r.record})
    if not records:
        return ""
    table = verdict_rows(rows)
    title = f"<h2>The record on file ({html.escape(', '.join(records))})</h2>"
    if not table:
        return title + "<p>no event it could be played against</p>"
    head = ["event (UTC)", "event", "checks passed", "worst check", "err / band", ""]
    return (
        title + "<p>Each event of the recordings played into the record as <code>phid validate</code> plays it.</p>"
        f'<img src="{_record_figure(rows)}" alt="the record\'s errors per channel over time">'
        + html_table(head, table, text_columns=(1, 2, 3, 5))
    )


def _sisters_section(unit: str, gaps: list[SisterGap]) -> str:
    mine = [g for g in gaps if unit in (g.first.unit, g.second.unit)]
    if not mine:
        return ""
    items = "".join(f"<li>{html.escape(g.text())}</li>" for g in mine)
    return f"<h2>Sister units that disagree</h2><ul>{items}</ul>"


def write_report(
    path: str | Path, unit: str, rows: list[Row], flagged: list[Change], gaps: list[SisterGap] | None = None
) -> Path:
    figure_backend()
    head = ["recorded (UTC)"] + [f"{SYMBOLS[n]} ({SPECS_BY_NAME[n].unit})" for n in PARAMETER_NAMES]
    head += ["recording", "note"]
    body = []
    for r in rows:
        when = _when(r.start_ns)
        note = f"FAILED: {r.error}" if r.status == "failed" else ", ".join(e["name"] for e in r.effects)
        values = [
            estimate_text(r.values.get(n, math.nan), r.stds.get(n, math.nan), bool(r.identifiable.get(n)))
            if r.status == "ok"
            else "—"
            for n in PARAMETER_NAMES
        ]
        body.append([when.strftime("%Y-%m-%d %H:%M") if when else "—", *values, Path(r.recording).name, note])
    alarms = (
        "".join(
            f"<li>{html.escape(SYMBOLS[c.parameter])} {c.relative:+.2%} ({c.sigmas:.1f} σ) between "
            f"{_when(c.before.start_ns):%Y-%m-%d %H:%M} and {_when(c.after.start_ns):%Y-%m-%d %H:%M}</li>"
            for c in flagged
        )
        or "<li>none</li>"
    )
    figure = _figure(rows, flagged)
    doc = f"""<!doctype html><html><head><meta charset="utf-8"><title>phid history: {html.escape(unit)}</title>
<style>{STYLE}</style></head><body>
<h1>Parameter history of unit {html.escape(unit)}</h1>
<h2>Flagged changes</h2><ul>{alarms}</ul>
<img src="{figure}" alt="parameters over time">
{_sisters_section(unit, gaps or [])}
{_record_section(rows)}
<h2>Recordings</h2>
<p>{html.escape(CONCISE_LEGEND)}</p>
{html_table(head, body, text_columns=(len(head) - 2, len(head) - 1))}
</body></html>"""
    p = Path(path)
    write_text(p, doc)
    return p
