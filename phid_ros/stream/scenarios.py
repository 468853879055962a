"""From a recording (bag, MCAP, CSV set) to the identification's scenarios.

A recording with scenario markers (a catalogue bag, a CSV set's manifest, a field import) is cut
where its markers say. One without markers is played through the online pipeline
(:func:`phid_ros.stream.replay.event_windows`), and its windows become scenarios by the very
conversion the recalibration worker uses: ``phid identify`` on a plant's recording sees the
windows a node would have cut, to the sample.
"""

from __future__ import annotations

import hashlib

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.ident.scenario import (
    DEFAULT_THRESHOLDS,
    ScenarioData,
    ScenarioError,
    StepThresholds,
    make_scenario,
)
from phid_ros.io.recording import MEASUREMENT_WINDOW_KEY, Recording
from phid_ros.model.channels import Frame
from phid_ros.model.conventions import NS
from phid_ros.stream.align import StreamHealth
from phid_ros.stream.recalibration import scenario_from_window


def aligned_frame(rec: Recording, source: str, windows: list[tuple[int, int]] | None = None) -> tuple[Frame, list[str]]:
    """All ten channels on one uniform grid, by the very aligner the online pipeline uses.

    So ``identify`` sees a recording exactly as ``replay`` does: a hole in the streams is a
    hole (NaN, and a window over it is skipped by name), not a splice of the samples either
    side; duplicate stamps keep their first value and are counted; a channel recorded in
    other units than per unit is refused with the unit it looks like. Returns the frame and
    notes on what was dropped. With ``windows`` (the scenarios'
    [start, end] stamps), a stream's gaps are noted only where they touch a window: the spaces
    between the scenarios of a CSV set are gaps by design and skip nothing.
    """
    from phid_ros.io.recording import block_bounds
    from phid_ros.io.topics import STREAMS_BY_NAME
    from phid_ros.model.channels import CHANNEL_INDEX
    from phid_ros.stream.align import Aligner

    check_streams(rec, source)
    period = rec.streams["pt_ct"].period_ns
    al = Aligner(period, stale_ns=2 * NS)
    for name, stream in rec.streams.items():
        if stream.channels and all(np.isnan(x).all() for x in stream.channels.values()):
            continue  # a stream the recorder did not carry (a field import's): its columns stay NaN
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
    if len(blocks) == 1:  # the usual case: one pull, one block (no 50 MB copy)
        t, values = blocks[0].t_ns, blocks[0].values
    else:
        t = np.concatenate([b.t_ns for b in blocks])
        values = np.asfortranarray(np.concatenate([b.values for b in blocks]))
    notes = dropped_notes(al.health, source)
    for name, h in al.health.items():
        if h.gaps and _gap_in_windows(t, values[:, CHANNEL_INDEX[STREAMS_BY_NAME[name].channels[0]]], windows):
            notes.append(f"{source}: stream {name}: {h.gaps} gap(s); windows over a gap are skipped")
    return Frame(t, values, period), notes


def check_streams(rec: Recording, source: str) -> None:
    """Refuse a recording that lacks a sensor stream or carries a channel in other units than per unit."""
    from phid_ros.io.topics import STREAMS
    from phid_ros.model.channels import unit_problem

    missing_streams = [s.name for s in STREAMS if s.name not in rec.streams]
    if missing_streams:
        raise PhidError(f"{source}: no {', '.join(missing_streams)} stream(s)")
    for stream in rec.streams.values():
        for c, x in stream.channels.items():
            problem = unit_problem(c, x)
            if problem:
                raise PhidError(f"{source}: {problem}")


def dropped_notes(health: dict[str, StreamHealth], source: str) -> list[str]:
    """What the aligner dropped from each stream, one line per cause."""
    notes = []
    for name, h in health.items():
        dropped = {
            "duplicate stamps (the first value of each stamp kept, later ones dropped)": h.duplicates,
            "out-of-order stamps": h.out_of_order,
            "non-finite values": h.nonfinite,
            "values outside the per-unit range": h.implausible,
            "zero stamps": h.zero_stamps,
            "wild stamps": h.wild_stamps,
            "messages whose channel arrays differ in length": h.malformed,
        }
        for what, count in dropped.items():
            if count:
                notes.append(f"{source}: stream {name}: {count} samples dropped: {what}")
    return notes


def _gap_in_windows(t: np.ndarray, column: np.ndarray, windows: list[tuple[int, int]] | None) -> bool:
    """Whether the aligner left a hole (NaN) in this stream inside any window (True without windows)."""
    if windows is None:
        return True
    holes = t[np.isnan(column)]
    return any(bool(np.any((holes >= a) & (holes <= b))) for a, b in windows)


def scenarios_from_recording(
    rec: Recording, source: str, thresholds: StepThresholds = DEFAULT_THRESHOLDS
) -> tuple[list[ScenarioData], list[str]]:
    """Scenario windows from the markers, or from the online pipeline's event windows when there are none."""
    if not rec.scenarios:
        return _detected_scenarios(rec, source, thresholds)
    marked = [(m.start_ns, m.end_ns) for m in rec.scenarios]
    frame, problems = aligned_frame(rec, source, marked)
    t = frame.t_ns
    window_s = float(rec.metadata.get(MEASUREMENT_WINDOW_KEY, 0.0))
    out: list[ScenarioData] = []
    seen: dict[bytes, list[tuple[str, np.ndarray]]] = {}
    for m in rec.scenarios:
        a = int(np.searchsorted(t, m.start_ns))
        b = int(np.searchsorted(t, m.end_ns, side="right"))
        if _seen_before(m.name, frame.values[a:b], seen, source, problems):
            continue
        try:
            out.append(
                make_scenario(
                    m.name,
                    frame.rows(a, b),
                    kind=m.kind,
                    role=m.role,
                    generator_damping=m.generator_damping,
                    k_event=int(np.searchsorted(t, m.event_ns)) - a if m.event_ns else None,
                    k_clear=int(np.searchsorted(t, m.clearing_ns)) - a if m.clearing_ns else None,
                    thresholds=thresholds,
                    measurement_window_s=window_s,
                )
            )
        except ScenarioError as exc:
            problems.append(f"{source}: skipped {exc}")
    return out, problems


def _detected_scenarios(
    rec: Recording, source: str, thresholds: StepThresholds
) -> tuple[list[ScenarioData], list[str]]:
    """A recording without markers: the disturbances the online pipeline finds, in its windows."""
    from phid_ros.stream.replay import event_windows

    check_streams(rec, source)
    windows, health = event_windows(rec, thresholds)
    problems = dropped_notes(health, source)
    if not windows:
        raise PhidError(
            f"{source}: no scenario markers and no disturbance found (no fault, torque step or voltage step)"
        )
    problems.append(f"{source}: no scenario markers: {len(windows)} disturbance(s) detected and cut into windows")
    window_s = float(rec.metadata.get(MEASUREMENT_WINDOW_KEY, 0.0))
    out: list[ScenarioData] = []
    seen: dict[bytes, list[tuple[str, np.ndarray]]] = {}
    for w in windows:
        name = w.event.event_id
        if not w.usable:
            problems.append(f"{source}: skipped {name}: {w.reason}")
            continue
        if w.reason:
            problems.append(f"{source}: {name}: {w.reason}; used as it is")
        if _seen_before(name, w.values, seen, source, problems):
            continue
        try:
            out.append(scenario_from_window(w, thresholds=thresholds, measurement_window_s=window_s))
        except ScenarioError as exc:
            problems.append(f"{source}: skipped {exc}")
    return out, problems


def _seen_before(
    name: str, values: np.ndarray, seen: dict[bytes, list[tuple[str, np.ndarray]]], source: str, problems: list[str]
) -> bool:
    """The same measurement listed twice would count twice and shrink every std by about sqrt(2).

    Windows are told apart by a digest of every 64th row, and only windows with the same digest
    are compared in full: hashing every byte of the windows (40 MB on the catalogue) cost 30 ms.
    """
    key = hashlib.sha256(np.ascontiguousarray(values[::64]).tobytes() + str(values.shape).encode()).digest()
    for earlier, data in seen.get(key, []):
        if np.array_equal(values, data, equal_nan=True):
            problems.append(f"{source}: skipped scenario {name}: the same data as scenario {earlier}")
            return True
    seen.setdefault(key, []).append((name, values))
    return False
