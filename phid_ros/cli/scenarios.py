"""From a recording (bag, MCAP, CSV set) to the identification's scenario windows."""

from __future__ import annotations

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.ident.scenario import CHANNELS, ScenarioData, ScenarioError, find_events, make_scenario
from phid_ros.io.recording import NS, Recording

PRE_EVENT_S = 1.0
POST_EVENT_S = 29.0


def aligned_channels(rec: Recording, source: str) -> tuple[np.ndarray, float, dict[str, np.ndarray]]:
    """All ten channels on the PT/CT stream's stamps.

    Streams recorded on the same clock and grid are used as they are; others are
    interpolated, and samples farther than two periods from the nearest sample
    of their stream become NaN, so a window over a gap is refused, not invented.
    """
    if "pt_ct" not in rec.streams:
        raise PhidError(f"{source}: no PT/CT stream")
    base = rec.streams["pt_ct"]
    t = base.t_ns
    if np.any(np.diff(t) <= 0):
        raise PhidError(
            f"{source}: PT/CT stamps are not increasing; replay it through the online pipeline "
            "(phid replay) which splits segments at clock jumps"
        )
    out: dict[str, np.ndarray] = {}
    for stream in rec.streams.values():
        same = len(stream.t_ns) == len(t) and np.array_equal(stream.t_ns, t)
        for c, x in stream.channels.items():
            if same:
                out[c] = x
                continue
            ts = stream.t_ns
            y = np.interp(t.astype(float), ts.astype(float), x)
            j = np.clip(np.searchsorted(ts, t), 1, len(ts) - 1)
            nearest = np.minimum(np.abs(t - ts[j - 1]), np.abs(ts[j] - t))
            y[nearest > 2 * stream.period_ns] = np.nan
            out[c] = y
    missing = [c for c in CHANNELS if c not in out]
    if missing:
        raise PhidError(f"{source}: channels {missing} missing")
    return t, base.period_ns / NS, out


def scenarios_from_recording(rec: Recording, source: str) -> tuple[list[ScenarioData], list[str]]:
    """Scenario windows from the markers, or from detected disturbances when there are none."""
    t, dt, ch = aligned_channels(rec, source)
    problems: list[str] = []
    out: list[ScenarioData] = []
    windows = []
    if rec.scenarios:
        for m in rec.scenarios:
            a = int(np.searchsorted(t, m.start_ns))
            b = int(np.searchsorted(t, m.end_ns, side="right"))
            k_ev = int(np.searchsorted(t, m.event_ns)) - a if m.event_ns else None
            k_cl = int(np.searchsorted(t, m.clearing_ns)) - a if m.clearing_ns else None
            windows.append((m.name, m.kind, m.role, m.generator_damping, a, b, k_ev, k_cl))
    else:
        events = find_events(ch, dt)
        if not events:
            raise PhidError(
                f"{source}: no scenario markers and no disturbance found (no fault, torque step or voltage step)"
            )
        pre, post = int(PRE_EVENT_S / dt), int(POST_EVENT_S / dt)
        for i, (kind, k, k_cl) in enumerate(events):
            a = max(0, k - pre)
            nxt = events[i + 1][1] - pre if i + 1 < len(events) else len(t)
            b = min(len(t), k + post, nxt)
            windows.append(
                (f"E{i + 1:02d}_{kind}", kind, "identify", True, a, b, k - a, None if k_cl is None else k_cl - a)
            )
        problems.append(f"no scenario markers: {len(events)} disturbance(s) detected and cut into windows")
    for name, kind, role, damping, a, b, k_ev, k_cl in windows:
        try:
            out.append(
                make_scenario(
                    name,
                    {c: x[a:b] for c, x in ch.items()},
                    dt,
                    kind=kind,
                    role=role,
                    generator_damping=damping,
                    k_event=k_ev,
                    k_clear=k_cl,
                    start_ns=int(t[a]),
                )
            )
        except ScenarioError as exc:
            problems.append(f"skipped: {exc}")
    return out, problems
