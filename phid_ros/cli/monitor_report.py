"""HTML reports of a monitoring run over a recording: ``phid replay --report`` and ``phid track --report``.

Both show the same three things over the recording's time axis: the events (on the
measured terminal voltage and mechanical power), the parameters with ±2σ bands and
their alarms, and the health of every sensor stream.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from phid_ros.cli.common import figure_backend, mark_withheld
from phid_ros.cli.html import STYLE, html_table, png_data_uri
from phid_ros.cli.tables import CONCISE_LEGEND, estimate_text
from phid_ros.fleet.history import DRIFT_SIGMAS
from phid_ros.io.files.outputs import write_text
from phid_ros.io.overview import Overview
from phid_ros.model.conventions import NS
from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME, SYMBOLS
from phid_ros.stream.levels import Level
from phid_ros.stream.output_bag import HealthSnapshot

if TYPE_CHECKING:
    from phid_ros.ident.results import Estimate
    from phid_ros.stream.pipeline import Outputs
    from phid_ros.stream.tracker import TrackPoint

KIND_COLORS = {"fault": "#c0392b", "torque_step": "#1f5fbf", "voltage_step": "#2e8b57", "field_step": "#8e44ad"}
LEVEL_COLORS = {Level.OK: "#2e8b57", Level.WARN: "#e69f00", Level.ERROR: "#c0392b", Level.STALE: "#888888"}
LEVEL_NAMES = {Level.OK: "green", Level.WARN: "orange", Level.ERROR: "red", Level.STALE: "grey"}


@dataclass
class ParameterPoint:
    """One published set: its stream time, the estimates, and which of them raised an alarm."""

    t_s: float
    estimates: dict[str, Estimate]
    alarmed: list[str] = field(default_factory=list)


@dataclass
class HealthLog:
    """Each stream's level and cumulative counters at stamps over the recording."""

    t_s: list[float] = field(default_factory=list)
    streams: dict[str, list[tuple[Level, int, int, int]]] = field(default_factory=dict)  # level, dropped, gaps, jumps

    def add(self, t_s: float, snapshot: dict[str, tuple[Level, int, int, int]]) -> None:
        self.t_s.append(t_s)
        for name, row in snapshot.items():
            self.streams.setdefault(name, []).append(row)


# -- figures ----------------------------------------------------------------------------------------
def _events_figure(
    overview: Overview, events: Sequence[tuple[str, float, bool]], marks: Sequence[tuple[float, str]]
) -> str:
    """V_t and P_m over the recording, each event a line in its kind's colour (dashed: window unusable)."""
    import matplotlib.pyplot as plt

    start = overview.span_ns()[0]
    # a channel never recorded is not drawn as an empty axis: P_e in P_m's place on a recorder's
    # day (P_m never carried), said on its axis; neither: V_t alone
    power = next(
        (
            (c, label)
            for c, label in (("p_m", "P_m (pu)"), ("p_e", "P_e (pu), P_m not recorded"))
            if len(overview.envelope(c)[0])
        ),
        None,
    )
    drawn = [("v_t", "V_t (pu)")] + ([power] if power else [])
    fig, axes = plt.subplots(
        len(drawn), 1, figsize=(10, 2.3 * len(drawn)), sharex=True, squeeze=False, layout="constrained"
    )
    axes = axes[:, 0]
    for ax, (channel, label) in zip(axes, drawn):
        t_ns, lo, hi = overview.envelope(channel)
        # min and max of each bin, so that a 100 ms fault dip is not decimated away
        ax.plot(np.repeat((t_ns - start) / NS, 2), np.column_stack((lo, hi)).ravel(), color="0.35", lw=0.6)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        for kind, t_ev, ok in events:
            ax.axvline(t_ev, color=KIND_COLORS.get(kind, "k"), lw=1.0, ls="-" if ok else "--", alpha=0.8)
    for t_m, color in marks:
        axes[0].plot([t_m], [axes[0].get_ylim()[1]], marker="v", color=color, ms=8, clip_on=False)
    handles = [plt.Line2D([], [], color=c, label=k.replace("_", " ")) for k, c in KIND_COLORS.items()]
    handles.append(plt.Line2D([], [], color="k", ls="--", label="window not usable"))
    if marks:
        handles.append(
            plt.Line2D(
                [], [], color="#2e8b57", marker="v", ls="", label="recalibration adopted (or its partial set published)"
            )
        )
        handles.append(plt.Line2D([], [], color="#c0392b", marker="v", ls="", label="recalibration not adopted"))
    axes[0].legend(handles=handles, fontsize=7, ncol=3, loc="lower left")
    axes[-1].set_xlabel("time from the start of the recording (s)")
    fig.suptitle("Events over the recording")
    return png_data_uri(fig)


def _parameters_figure(points: Sequence[ParameterPoint], names: Sequence[str], title: str) -> str | None:
    """Each parameter over time: the estimate, a ±2σ band, a tick on the axis where withheld, alarms ringed."""
    import matplotlib.pyplot as plt

    if not points:
        return None
    rows = math.ceil(len(names) / 2)
    fig, axes = plt.subplots(rows, 2, figsize=(10, 2.1 * rows), sharex=True, layout="constrained", squeeze=False)
    t = np.array([p.t_s for p in points])
    for ax, name in zip(axes.ravel(), names):
        v = np.array([p.estimates[name].value if name in p.estimates else math.nan for p in points])
        sd = np.array([p.estimates[name].std if name in p.estimates else math.nan for p in points])
        ok = np.array([name in p.estimates and p.estimates[name].identifiable for p in points])
        if ok.any():
            ax.errorbar(
                t[ok], v[ok], yerr=2 * sd[ok], fmt="o-", color="#1f5fbf", ms=3, lw=1.0, capsize=3, label="estimate ±2σ"
            )
        mark_withheld(ax, t[~ok])
        alarm = np.array([name in p.alarmed for p in points]) & ok
        if alarm.any():
            ax.plot(t[alarm], v[alarm], "o", mfc="none", mec="#c0392b", ms=11, mew=1.8, label="alarm")
        unit = SPECS_BY_NAME[name].unit
        ax.set_ylabel(f"{SYMBOLS[name]} ({unit})")
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(names) :]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("time from the start of the recording (s)")
    handles, labels = [], []
    for ax in axes.ravel():
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    axes[0][0].legend(handles, labels, fontsize=7, loc="best")
    fig.suptitle(title)
    return png_data_uri(fig)


def _health_figure(log: HealthLog) -> str | None:
    """Per stream: a strip of its diagnostic level over time, and its cumulative losses beneath."""
    import matplotlib.pyplot as plt

    if not log.t_s:
        return None
    names = list(log.streams)
    t = np.array(log.t_s)
    fig, (ax_level, ax_count) = plt.subplots(
        2,
        1,
        figsize=(10, 1.2 + 0.45 * len(names) + 2.4),
        sharex=True,
        layout="constrained",
        gridspec_kw={"height_ratios": [0.45 * len(names) + 0.4, 2.4]},
    )
    for row, name in enumerate(names):
        levels = [r[0] for r in log.streams[name]]
        edges = np.append(t, t[-1] + (t[-1] - t[-2] if len(t) > 1 else 1.0))
        for k, level in enumerate(levels):
            ax_level.barh(row, edges[k + 1] - edges[k], left=edges[k], color=LEVEL_COLORS.get(level, "k"), height=0.7)
        counts = np.array([r[1:] for r in log.streams[name]])
        ax_count.step(t, counts[:, 0], where="post", lw=1.0, label=f"{name} dropped")
        ax_count.step(t, counts[:, 1], where="post", lw=1.0, ls="--", label=f"{name} gaps")
        if counts[:, 2].any():
            ax_count.step(t, counts[:, 2], where="post", lw=1.4, ls=":", label=f"{name} clock jumps")
    ax_level.set_yticks(range(len(names)), names)
    ax_level.invert_yaxis()
    ax_level.set_title(
        "diagnostic level: " + ", ".join(f"{k} {v}" for k, v in LEVEL_NAMES.items()),
        fontsize=9,
    )
    ax_count.set_ylabel("count since start")
    # counts are whole and never negative: all-zero counts let matplotlib centre the axis on 0 (−0.04 … 0.04)
    ax_count.set_ylim(bottom=0, top=max(1.0, ax_count.get_ylim()[1]))
    ax_count.yaxis.get_major_locator().set_params(integer=True)
    ax_count.grid(alpha=0.3)
    ax_count.legend(fontsize=7, ncol=4)
    ax_count.set_xlabel("time from the start of the recording (s)")
    fig.suptitle("Stream health over time")
    return png_data_uri(fig)


def _parameter_rows(points: Sequence[ParameterPoint], names: Sequence[str]) -> tuple[list[str], list[list[str]]]:
    head = ["t s"] + [f"{SYMBOLS[n]} ({SPECS_BY_NAME[n].unit})" for n in names] + ["alarms"]
    rows = []
    for p in points:
        cells = [f"{p.t_s:.1f}"]
        for n in names:
            e = p.estimates.get(n)
            cells.append(estimate_text(e.value, e.std, e.identifiable) if e else "—")
        cells.append(", ".join(SYMBOLS[n] for n in p.alarmed))
        rows.append(cells)
    return head, rows


def _page(title: str, source: str, intro: str, sections: Sequence[str]) -> str:
    head = f"{html.escape(title)}: {html.escape(source)}"
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>{head}</title>
<style>{STYLE}</style></head><body>
<h1>{html.escape(title)}</h1>
<p>Input: <code>{html.escape(source)}</code> &middot; {intro}</p>
{"".join(sections)}
</body></html>"""


def _figure(heading: str, img: str | None, alt: str) -> str:
    return f'<h2>{html.escape(heading)}</h2><img src="{img}" alt="{html.escape(alt)}">' if img else ""


def _write(path: str | Path, page: str) -> Path:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text(out, page)
    return out


# -- replay ------------------------------------------------------------------------------------------
def replay_alarms(points: list[ParameterPoint], sigmas: float = DRIFT_SIGMAS) -> None:
    """Mark a parameter whose accepted value moved beyond ``sigmas`` combined σ since the previous set."""
    for prev, cur in zip(points, points[1:]):
        for n, e in cur.estimates.items():
            p = prev.estimates.get(n)
            if p is None or not (e.identifiable and p.identifiable):
                continue
            band = sigmas * math.hypot(e.std, p.std)
            if math.isfinite(band) and abs(e.value - p.value) > band:
                cur.alarmed.append(n)


def write_replay_report(
    path: str | Path, overview: Overview, outputs: Outputs, health_log: list[HealthSnapshot], source: str
) -> Path:
    """``health_log``: each stream's health at every diagnostics stamp (replay's ``OutputCollector.health_log``)."""
    figure_backend()
    start = overview.span_ns()[0]
    usable = {w.event.event_id: w.usable for w in outputs.windows}
    events = [(e.kind, (e.inception_ns - start) / NS, usable.get(e.event_id, False)) for e in outputs.events]
    # a partial set (the parameters a recorder's channels determine, before any set of eight) is
    # published as the terminal says: drawn and tabled with its values, not marked "not adopted"
    published = [r for r in outputs.recalibrations if (r.accepted and r.result is not None) or r.determined]
    marks = [
        ((r.stream_time_ns - start) / NS, "#2e8b57" if r in published else "#c0392b") for r in outputs.recalibrations
    ]
    points = [
        ParameterPoint(
            (r.stream_time_ns - start) / NS,
            dict(r.result.estimates) if r.accepted and r.result is not None else dict(r.determined),
        )
        for r in published
    ]
    partial = sum(not r.accepted for r in published)
    replay_alarms(points)
    health = HealthLog()
    for t_ns, snap in health_log:
        health.add((t_ns - start) / NS, snap)
    from phid_ros.stream.detector import severity_text, window_status

    reasons = {w.event.event_id: window_status(w) for w in outputs.windows}
    settled = {w.event.event_id: w.settled for w in outputs.windows}

    ev_rows = [
        [
            f"{(e.inception_ns - start) / NS:.3f}",
            e.kind,
            e.name or "—",
            severity_text(e.kind, e.severity, settled.get(e.event_id)),
            reasons.get(e.event_id, "pending"),
        ]
        for e in outputs.events
    ]
    rc_rows = [
        [
            f"{(r.stream_time_ns - start) / NS:.1f}",
            str(len(r.event_ids)),
            *r.said(),
        ]
        for r in outputs.recalibrations
    ]
    head, prow = _parameter_rows(points, PARAMETER_NAMES)
    span = (overview.span_ns()[1] - start) / NS
    sections = [
        _figure("Events", _events_figure(overview, events, marks), "events timeline"),
        html_table(["t s", "kind", "scenario", "severity", "window"], ev_rows),
        _figure(
            "Parameters over time",
            _parameters_figure(points, PARAMETER_NAMES, "Parameters of each adopted recalibration (±2σ)"),
            "parameters over time",
        ),
        f"<p>{html.escape(CONCISE_LEGEND)}. Alarm: a change beyond {DRIFT_SIGMAS:g} combined σ since the "
        "previous adopted set.</p>",
        html_table(head, prow) if prow else "<p>No recalibration was adopted.</p>",
        "<h2>Recalibrations</h2>",
        html_table(["t s", "events", "outcome", "why"], rc_rows),
        *_record_sections(outputs, start),
        _figure("Stream health", _health_figure(health), "stream health over time"),
    ]
    adopted = f"{len(points) - partial} adopted recalibrations"
    if partial:
        adopted += f" &middot; {partial} partial set(s) published (the parameters the channels determine)"
    intro = f"{span:.1f} s of data &middot; {len(outputs.events)} events &middot; {adopted}"
    return _write(path, _page("phid replay", source, intro, sections))


def _record_sections(outputs: Outputs, start: int) -> list[str]:
    """The record on file against each event (``--record``): its checks, its state after each
    event, the drift, and the overlays of the first failing events."""
    if not outputs.verdicts:
        return []
    from phid_ros.cli.validate import CHECK_CELLS, check_cells, overlay_figure

    final = list({v.event_id: v for v in outputs.verdicts}.values())  # an event played again: its last
    rows = [
        [f"{(v.stream_time_ns - start) / NS:.1f}", v.event_id, *check_cells(c), str(v.level)]
        for v in final
        for c in v.checks
    ]
    last = max(final, key=lambda v: v.stream_time_ns)  # the newest event's: the state at the end
    head = ["end s", "event", *CHECK_CELLS, "state"]
    overlays = "".join(
        f"<h3>{html.escape(v.event_id)} ({html.escape(v.kind)})</h3>"
        f'<img src="{png_data_uri(overlay_figure(v.overlay))}" alt="{html.escape(v.event_id)}">'
        for v in final
        if v.overlay is not None
    )
    drift = "".join(f"<li>{html.escape(d)}</li>" for d in last.drifting) or "<li>none</li>"
    return [
        f"<h2>The record on file against each event</h2><p><code>{html.escape(last.record)}</code>, played in as "
        f"<code>phid validate</code> plays it. State at the end: <b>{last.level}</b>: "
        f"{html.escape(last.status)}</p>",
        html_table(head, rows, text_columns=(1,)),
        "<h3>Drifting from the record (the last recalibration's determined parameters)</h3><ul>" + drift + "</ul>",
        f"<h3>Failing events, recorded against simulated</h3>{overlays}" if overlays else "",
    ]


# -- track -------------------------------------------------------------------------------------------
def write_track_report(
    path: str | Path,
    overview: Overview,
    track: Sequence[TrackPoint],
    health: HealthLog,
    source: str,
    notes: Sequence[str],
    settings: str,
) -> Path:
    from phid_ros.stream.tracker import TRACKED

    figure_backend()
    start = overview.span_ns()[0]
    seen: dict[int, str] = {}
    for p in track:
        for kind, t_ns in p.steps:
            if all(abs(t_ns - t) > NS for t in seen):
                seen[t_ns] = kind
    events = [(kind, (t - start) / NS, True) for t, kind in sorted(seen.items())]
    points = [ParameterPoint((p.t_ns - start) / NS, p.estimates, list(p.alarmed)) for p in track]
    head, rows = _parameter_rows(points, TRACKED)
    alarms = [f"<li>{(p.t_ns - start) / NS:.0f} s: {html.escape(a)}</li>" for p in track for a in p.alarms]
    sections = [
        _figure("Events", _events_figure(overview, events, []), "events timeline"),
        _figure(
            "Parameters over time",
            _parameters_figure(points, TRACKED, "Tracked parameters at the end of each window (±2σ)"),
            "parameters over time",
        ),
        f"<p>{html.escape(CONCISE_LEGEND)}. X_d and X_q are held at the base set; see the notes.</p>",
        html_table(head, rows),
        "<h2>Drift alarms</h2><ul>" + ("".join(alarms) or "<li>none</li>") + "</ul>",
        _figure("Stream health", _health_figure(health), "stream health over time"),
        "<h2>Notes</h2><ul>" + ("".join(f"<li>{html.escape(n)}</li>" for n in notes) or "<li>none</li>") + "</ul>",
    ]
    return _write(path, _page("phid track", source, html.escape(settings), sections))
