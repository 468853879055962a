"""From a recording (bag, MCAP, CSV set) to the identification's scenario windows."""

from __future__ import annotations

import hashlib

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.ident.scenario import (
    CHANNELS,
    DEFAULT_THRESHOLDS,
    ScenarioData,
    ScenarioError,
    StepThresholds,
    find_events,
    make_scenario,
)
from phid_ros.io.recording import MEASUREMENT_WINDOW_KEY, Recording
from phid_ros.model.conventions import NS
from phid_ros.stream.detector import POST_EVENT_S, PRE_EVENT_S


def aligned_channels(
    rec: Recording, source: str, windows: list[tuple[int, int]] | None = None
) -> tuple[np.ndarray, float, dict[str, np.ndarray], list[str]]:
    """All ten channels on one uniform grid, by the very aligner the online pipeline uses.

    So ``identify`` sees a recording exactly as ``replay`` does: a hole in the streams is a
    hole (NaN, and a window over it is skipped by name), not a splice of the samples either
    side; duplicate stamps keep their first value and are counted; a channel recorded in
    other units than per unit is refused with the unit it looks like. Returns the grid, the
    period in s, the channels and notes on what was dropped. With ``windows`` (the scenarios'
    [start, end] stamps), a stream's gaps are noted only where they touch a window: the spaces
    between the scenarios of a CSV set are gaps by design and skip nothing.
    """
    from phid_ros.io.recording import block_bounds
    from phid_ros.io.topics import CHANNEL_INDEX, STREAMS, STREAMS_BY_NAME, channel_columns, unit_problem
    from phid_ros.stream.align import Aligner

    missing_streams = [s.name for s in STREAMS if s.name not in rec.streams]
    if missing_streams:
        raise PhidError(f"{source}: no {', '.join(missing_streams)} stream(s)")
    for stream in rec.streams.values():
        for c, x in stream.channels.items():
            problem = unit_problem(c, x)
            if problem:
                raise PhidError(f"{source}: {problem}")
    period = rec.streams["pt_ct"].period_ns
    al = Aligner(period, stale_ns=2 * NS)
    for name, stream in rec.streams.items():
        # one ingest per run of uniform stamps: vectorised, and a gap or duplicate starts a new run
        for a, b in block_bounds(stream.t_ns, stream.period_ns, len(stream.t_ns) or 1):
            al.ingest(name, int(stream.t_ns[a]), stream.period_ns, {c: x[a:b] for c, x in stream.channels.items()})
    blocks = al.pull(final=True)
    if not blocks:
        raise PhidError(f"{source}: the sensor streams do not overlap in time")
    if any(b.segment != blocks[0].segment for b in blocks):
        raise PhidError(
            f"{source}: the stamps jump back in time (clock reset or looped recording); replay it through "
            "the online pipeline (phid replay), which splits segments at clock jumps"
        )
    t = np.concatenate([b.t_ns for b in blocks])
    values = np.concatenate([b.values for b in blocks])
    notes = []
    for name, h in al.health.items():
        dropped = {
            "duplicate stamps (the first value of each stamp kept, later ones dropped)": h.duplicates,
            "out-of-order stamps": h.out_of_order,
            "non-finite values": h.nonfinite,
            "values outside the per-unit range": h.implausible,
            "zero stamps": h.zero_stamps,
            "wild stamps": h.wild_stamps,
        }
        for what, count in dropped.items():
            if count:
                notes.append(f"{source}: stream {name}: {count} samples dropped: {what}")
        if h.gaps and _gap_in_windows(t, values[:, CHANNEL_INDEX[STREAMS_BY_NAME[name].channels[0]]], windows):
            notes.append(f"{source}: stream {name}: {h.gaps} gap(s); windows over a gap are skipped")
    return t, period / NS, channel_columns(values), notes


def _gap_in_windows(t: np.ndarray, column: np.ndarray, windows: list[tuple[int, int]] | None) -> bool:
    """Whether the aligner left a hole (NaN) in this stream inside any window (True without windows)."""
    if windows is None:
        return True
    holes = t[np.isnan(column)]
    return any(bool(np.any((holes >= a) & (holes <= b))) for a, b in windows)


def scenarios_from_recording(
    rec: Recording, source: str, thresholds: StepThresholds = DEFAULT_THRESHOLDS
) -> tuple[list[ScenarioData], list[str]]:
    """Scenario windows from the markers, or from detected disturbances when there are none."""
    marked = [(m.start_ns, m.end_ns) for m in rec.scenarios] if rec.scenarios else None
    t, dt, ch, problems = aligned_channels(rec, source, marked)
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
        from phid_ros.stream.detector import forward_filled

        events = find_events(
            {c: forward_filled(x) for c, x in ch.items()}, dt, thresholds=thresholds
        )  # as the online detector sees them
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
        problems.append(f"{source}: no scenario markers: {len(events)} disturbance(s) detected and cut into windows")
    seen: dict[bytes, str] = {}
    for name, kind, role, damping, a, b, k_ev, k_cl in windows:
        # the same measurement listed twice would count twice and shrink every std by about sqrt(2)
        digest = hashlib.sha256(np.ascontiguousarray([ch[c][a:b] for c in CHANNELS]).tobytes()).digest()
        if digest in seen:
            problems.append(f"{source}: skipped scenario {name}: the same data as scenario {seen[digest]}")
            continue
        seen[digest] = name
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
                    thresholds=thresholds,
                    measurement_window_s=float(rec.metadata.get(MEASUREMENT_WINDOW_KEY, 0.0)),
                )
            )
        except ScenarioError as exc:
            problems.append(f"{source}: skipped {exc}")
    return out, problems
