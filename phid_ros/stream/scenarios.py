"""From a recording (bag, MCAP, CSV set) to the identification's scenarios.

A recording with scenario markers (a catalogue bag, a CSV set's manifest, a field import) is cut
where its markers say; a marked window without an event stamp (a test file imported whole) that
holds several events (a step and its return) is cut into one scenario per event
(:mod:`phid_ros.ident.file_events`). One without markers is played through the online pipeline
(:func:`phid_ros.stream.replay.event_windows`), and its windows become scenarios by the very
conversion the recalibration worker uses: ``phid identify`` on a plant's recording sees the
windows a node would have cut, to the sample.
"""

from __future__ import annotations

import hashlib

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.ident.file_events import FileEvent, event_note, events_of_file
from phid_ros.ident.scenario import (
    DEFAULT_THRESHOLDS,
    ScenarioData,
    ScenarioError,
    StepThresholds,
    make_scenario,
)
from phid_ros.io.parts import RecordingParts
from phid_ros.io.recording import MEASUREMENT_WINDOW_KEY, Recording, ScenarioInfo
from phid_ros.model.channels import Frame
from phid_ros.model.conventions import NS
from phid_ros.stream.align import StreamHealth
from phid_ros.stream.detector import EventWindow
from phid_ros.stream.recalibration import scenario_from_window
from phid_ros.stream.recorder import on_stamps


def aligned_frame(
    rec: Recording,
    source: str,
    windows: list[tuple[int, int]] | None = None,
    health: dict[str, StreamHealth] | None = None,
) -> tuple[Frame, list[str]]:
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
    for name, stream in rec.sensor_streams().items():
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
    if health is None:
        notes = dropped_notes(al.health, source)
    else:  # windows aligned one by one: their counts summed, said once for the recording
        notes = []
        for name, h in al.health.items():
            total = health.setdefault(name, StreamHealth(name))
            for f in DROP_COUNTERS:
                setattr(total, f, getattr(total, f) + getattr(h, f))
    for name, h in al.health.items():
        if h.gaps and _gap_in_windows(t, values[:, CHANNEL_INDEX[STREAMS_BY_NAME[name].channels[0]]], windows):
            notes.append(f"{source}: stream {name}: {h.gaps} gap(s); windows over a gap are skipped")
    return Frame(t, values, period), notes


def recorder_columns(rec: Recording, t_ns: np.ndarray) -> dict[str, np.ndarray]:
    """A recorder's own channels on the frame's stamps ``t_ns`` (:func:`~phid_ros.stream.recorder.on_stamps`:
    the rule the online pipeline's windows follow too)."""
    out: dict[str, np.ndarray] = {}
    for stream in rec.recorder_streams().values():
        if len(stream):
            order = np.argsort(stream.t_ns, kind="stable")
            channels = {c: x[order] for c, x in stream.channels.items()}
            out.update(on_stamps(stream.t_ns[order], channels, stream.period_ns, t_ns))
    return out


def check_streams(rec: Recording, source: str) -> None:
    """Refuse a recording that lacks a sensor stream or carries a channel in other units than per unit."""
    from phid_ros.io.topics import STREAMS

    missing_streams = [s.name for s in STREAMS if s.name not in rec.streams]
    if missing_streams:
        raise PhidError(f"{source}: no {', '.join(missing_streams)} stream(s)")
    check_streams_units(rec, source)


def check_part(part: Recording, source: str) -> None:
    """A part of a recording read in parts: its channels' units and its streams' clocks, as
    :func:`phid_ros.api.load_recording` checks a whole one."""
    from phid_ros.io.field.clock_check import clock_problems

    check_streams_units(part, source)
    problems = clock_problems(part)
    if problems:
        raise PhidError(f"{source}: {problems[0]}")


def check_streams_units(rec: Recording, source: str) -> None:
    """Refuse a recording (or a part of one) with a channel in other units than per unit."""
    from phid_ros.model.channels import unit_problem

    for stream in rec.streams.values():
        for c, x in stream.channels.items():
            problem = unit_problem(c, x)
            if problem:
                raise PhidError(f"{source}: {problem}")


DROP_COUNTERS = (
    "duplicates",
    "out_of_order",
    "nonfinite",
    "implausible",
    "zero_stamps",
    "wild_stamps",
    "malformed",
)


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
    out: list[ScenarioData] = []
    problems: list[str] = []
    _marked_scenarios(rec, source, thresholds, out, problems, {})
    return out, problems


def _marked_scenarios(
    rec: Recording,
    source: str,
    thresholds: StepThresholds,
    out: list[ScenarioData],
    problems: list[str],
    seen: dict[bytes, list[tuple[str, np.ndarray]]],
    health: dict[str, StreamHealth] | None = None,
) -> None:
    """The scenarios of ``rec``'s markers into ``out``, its notes into ``problems`` (what the
    aligner dropped summed into ``health`` instead, when given)."""
    marked = [(m.start_ns, m.end_ns) for m in rec.scenarios]
    frame, notes = aligned_frame(rec, source, marked, health)
    problems += notes
    t = frame.t_ns
    kept = recorder_columns(rec, t)
    window_s = float(rec.metadata.get(MEASUREMENT_WINDOW_KEY, 0.0))
    for m in rec.scenarios:
        a = int(np.searchsorted(t, m.start_ns))
        b = int(np.searchsorted(t, m.end_ns, side="right"))
        if seen_before(m.name, frame.values[a:b], seen, source, problems):
            continue
        pieces: list[FileEvent] = []
        whole_kind: str | None = m.kind
        whole: FileEvent | None = None  # a file's one event: its window from the plateau before it
        k_event = int(np.searchsorted(t, m.event_ns)) - a if m.event_ns else None
        if not m.event_ns:
            pieces, whole_kind, whole = _file_events(m, frame.rows(a, b), thresholds, source, problems)
            if whole is not None:
                a, k_event = a + whole.start, whole.event - whole.start
        if whole_kind is None:  # its one event, or every one, is a lost measurement
            continue
        try:
            if not pieces:
                made = make_scenario(
                    m.name,
                    frame.rows(a, b),
                    kind=whole_kind,
                    role=m.role,
                    generator_damping=m.generator_damping,
                    k_event=k_event,
                    k_clear=int(np.searchsorted(t, m.clearing_ns)) - a if m.clearing_ns else None,
                    thresholds=thresholds,
                    measurement_window_s=window_s,
                    regulator=m.regulator,
                    recorded={c: x[a:b] for c, x in kept.items()},
                    reference_step=m.reference_step,
                )
                if whole is not None:
                    made.notes.append(f"{WHOLE_NOTE}: {whole.describe(frame.period_ns / NS)}")
                if whole is not None and made.kind == "field_step":
                    # its steady state the second half of the span after it, as the monitor takes it
                    made.steady_start = whole.steady_start - whole.start
                out.append(made)
        except ScenarioError as exc:
            problems.append(f"{source}: skipped {exc}")
        for e in pieces:
            name = event_name(m.name, e, frame.period_ns)
            try:
                made = make_scenario(
                    name,
                    frame.rows(a + e.start, a + e.end),
                    kind=m.kind if m.kind != "unknown" else e.kind,
                    role=m.role,
                    generator_damping=m.generator_damping,
                    k_event=e.event - e.start,
                    thresholds=thresholds,
                    measurement_window_s=window_s,
                    regulator=m.regulator,
                    recorded={c: x[a + e.start : a + e.end] for c, x in kept.items()},
                    reference_step=m.reference_step,
                )
            except ScenarioError as exc:
                problems.append(f"{source}: skipped {exc}")
                continue
            made.steady_start = e.steady_start - e.start
            made.notes.append(event_note(e, frame.period_ns / NS, m.name))
            made.file_time_s = e.event * frame.period_ns / NS
            out.append(made)


def event_name(recording: str, e: FileEvent, period_ns: int) -> str:
    """A file's event as a scenario's name: the file's and the event's time in it."""
    return f"{recording}@{e.event * period_ns / NS:.1f}s"


def _file_events(
    m: ScenarioInfo, frame: Frame, thresholds: StepThresholds, source: str, problems: list[str]
) -> tuple[list[FileEvent], str | None, FileEvent | None]:
    """A marked window without an event stamp (a test file imported whole) cut into its events,
    when it holds more than one; ([], the kind to prepare it whole with, its one event or None)
    when it holds one or none (kind None: its one event is a lost measurement, left out). The
    offsets are the window's; the one event's window runs from its plateau to the window's end,
    its event at the sample the monitor's detector finds it (the same function)."""
    if len(frame) < 2:
        return [], m.kind, None
    dt = frame.period_ns / NS
    events = events_of_file(frame.columns(), dt, thresholds=thresholds)
    if len(events) == 1 and events[0].lost_measurement:
        problems.append(f"{source}: skipped scenario {m.name}: {LOST_NOTE}")
        return [], None, None
    for e in events:
        if e.joined:
            problems.append(f"{source}: {m.name}: {e.joined_note(dt)}")
    if len(events) == 1 and events[0].joined:  # one event whose transient held a second detection
        return events, m.kind, None
    if len(events) < 2:
        plateau = events[0].start if events else 0
        if plateau:
            problems.append(
                f"{source}: {m.name} taken from {plateau * dt:.2f} s, the plateau before its event at "
                f"{events[0].event * dt:.2f} s (what came before is not its steady state)"
            )
        # at no load a fall of V_t is the field's (a de-excitation), never a fault
        return [], (events[0].kind if events and m.kind == "unknown" else m.kind), (events[0] if events else None)
    kept = []
    for e in events:
        if e.lost_measurement:
            problems.append(f"{source}: skipped {event_name(m.name, e, frame.period_ns)}: {LOST_NOTE}")
        else:
            kept.append(e)
    problems.append(
        f"{source}: {m.name} holds {len(events)} events, each its own scenario: "
        + "; ".join(e.describe(dt) for e in events)
    )
    if not kept:  # every event the measurement's: nothing of the machine (whole, it read as a fault)
        return [], None, None
    return kept, m.kind, None


WHOLE_NOTE = "its event found in the file as the monitor's detector finds it"
LOST_NOTE = (
    "V_t fell at once at no load (or had not come back): a terminal-voltage measurement lost (VT), not the machine"
)


def _detected_scenarios(
    rec: Recording, source: str, thresholds: StepThresholds
) -> tuple[list[ScenarioData], list[str]]:
    """A recording without markers: the disturbances the online pipeline finds, in its windows."""
    from phid_ros.stream.replay import event_windows

    check_streams(rec, source)
    windows, health = event_windows(rec, thresholds)
    return _window_scenarios(windows, health, source, thresholds, float(rec.metadata.get(MEASUREMENT_WINDOW_KEY, 0.0)))


def _window_scenarios(
    windows: list[EventWindow],
    health: dict[str, StreamHealth],
    source: str,
    thresholds: StepThresholds,
    window_s: float,
    dropped: list[str] | None = None,
) -> tuple[list[ScenarioData], list[str]]:
    """The online pipeline's event windows as scenarios (unusable and repeated ones named and left out)."""
    problems = dropped_notes(health, source) + (dropped or [])
    if not windows:
        raise PhidError(
            f"{source}: no scenario markers and no disturbance found (no fault, torque step or voltage step)"
        )
    problems.append(f"{source}: no scenario markers: {len(windows)} disturbance(s) detected and cut into windows")
    out: list[ScenarioData] = []
    seen: dict[bytes, list[tuple[str, np.ndarray]]] = {}
    for w in windows:
        name = w.event.event_id
        if not w.usable:
            problems.append(f"{source}: skipped {name}: {w.reason}")
            continue
        if w.reason:
            problems.append(f"{source}: {name}: {w.reason}; used as it is")
        if seen_before(name, w.values, seen, source, problems):
            continue
        try:
            out.append(scenario_from_window(w, thresholds=thresholds, measurement_window_s=window_s))
        except ScenarioError as exc:
            problems.append(f"{source}: skipped {exc}")
    return out, problems


def seen_before(
    name: str, values: np.ndarray, seen: dict[bytes, list[tuple[str, np.ndarray]]], source: str, problems: list[str]
) -> bool:
    """The same measurement listed twice would count twice and shrink every std by about sqrt(2)
    (within a recording, and across the recordings of one identification).

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


# a long recording without markers: at most this many windows of each kind are identified, the
# largest disturbances (a day of ambient data holds thousands of small steps; their windows, not
# the hours, are what identification holds and what its cost grows with)
MAX_WINDOWS_PER_KIND = 40


def scenarios_from_parts(
    parts: RecordingParts,
    source: str,
    thresholds: StepThresholds = DEFAULT_THRESHOLDS,
    max_per_kind: int = MAX_WINDOWS_PER_KIND,
) -> tuple[list[ScenarioData], list[str]] | None:
    """:func:`scenarios_from_recording` over a recording read part by part, holding only the
    scenarios' windows: each marker's samples, or the online pipeline's event windows (the
    ``max_per_kind`` largest of each kind). None when the recording's summary does not say
    whether it has markers (read it whole then)."""
    markers = parts.marker_count()
    if markers is None:
        return None
    return (
        _marked_parts(parts, source, thresholds)
        if markers
        else _detected_parts(parts, source, thresholds, max_per_kind)
    )


def _marked_parts(
    parts: RecordingParts, source: str, thresholds: StepThresholds
) -> tuple[list[ScenarioData], list[str]]:
    """Each marker's window cut out of the parts as they pass, then aligned and prepared window by
    window. A marker is usually logged at its window's start, before its samples; any order is
    valid MCAP, so a marker whose window reaches into parts already passed has the recording
    walked a second time, every marker known (before, its scenario was dropped)."""
    from phid_ros.io.recording import StreamSamples

    markers, pieces, period, late = _cut_marked(parts, source, None)
    if late:
        _, pieces, period, _ = _cut_marked(RecordingParts(parts.path, parts.part_messages), source, markers)
    out: list[ScenarioData] = []
    problems: list[str] = []
    seen: dict[bytes, list[tuple[str, np.ndarray]]] = {}
    health: dict[str, StreamHealth] = {}
    for k, m in enumerate(markers):
        got = pieces.pop(k, {})
        streams = {
            name: StreamSamples(
                np.concatenate([t for t, _ in got[name]]),
                period[name],
                {c: np.concatenate([ch[c] for _, ch in got[name]]) for c in got[name][0][1]},
            )
            for name in got
        }
        window = Recording(streams=streams, scenarios=[m], metadata=dict(parts.metadata))
        try:
            _marked_scenarios(window, source, thresholds, out, problems, seen, health)
        except PhidError as exc:  # a window with no samples, or a stream missing in it
            problems.append(f"{source}: skipped scenario {m.name}: {exc}")
    problems[:0] = dropped_notes(health, source)  # in the scenarios' windows, where it matters
    problems += parts.warnings
    return out, problems


Pieces = dict[int, dict[str, list[tuple[np.ndarray, dict[str, np.ndarray]]]]]


def _cut_marked(
    parts: RecordingParts, source: str, known: list[ScenarioInfo] | None
) -> tuple[list[ScenarioInfo], Pieces, dict[str, int], bool]:
    """One walk: the markers (``known``, or as they come), each one's samples, the streams'
    periods, and whether a marker came after parts that held samples of its window."""
    pieces: Pieces = {}
    markers: list[ScenarioInfo] = list(known) if known is not None else []
    period: dict[str, int] = {}
    passed: list[tuple[int, int]] = []  # the stamp span of each part walked
    late = False
    for part in parts:
        check_part(part, source)
        if known is None:
            late = late or any(lo <= m.end_ns and m.start_ns <= hi for m in part.scenarios for lo, hi in passed)
            markers += part.scenarios
        spans = [(int(st.t_ns.min()), int(st.t_ns.max())) for st in part.streams.values() if st.t_ns.size]
        if spans:
            passed.append((min(a for a, _ in spans), max(b for _, b in spans)))
        for name, stream in part.streams.items():
            period.setdefault(name, stream.period_ns)
            for k, m in enumerate(markers):
                # by mask, in file order: a duplicate or a clock that went back is the aligner's to judge
                at = np.flatnonzero((stream.t_ns >= m.start_ns) & (stream.t_ns <= m.end_ns))
                if at.size:
                    chans = {c: x[at] for c, x in stream.channels.items()}
                    pieces.setdefault(k, {}).setdefault(name, []).append((stream.t_ns[at], chans))
    return markers, pieces, period, late


def _detected_parts(
    parts: RecordingParts, source: str, thresholds: StepThresholds, max_per_kind: int
) -> tuple[list[ScenarioData], list[str]]:
    """The online pipeline over the parts; its usable windows kept, the largest of each kind."""
    import heapq

    from phid_ros.stream.detector import DetectorSettings
    from phid_ros.stream.pipeline import MonitorPipeline, Outputs, PipelineSettings
    from phid_ros.stream.replay import Player

    kept: dict[str, list[tuple[float, int, EventWindow]]] = {}
    unusable: list[EventWindow] = []
    order = [0]
    dropped = [0]

    def keep(out: Outputs) -> None:
        for w in out.windows:
            if not w.usable:
                unusable.append(w.light())
                continue
            heap = kept.setdefault(w.event.kind, [])
            order[0] += 1
            item = (abs(w.event.severity), -order[0], w)  # the largest kept; of equal ones the earliest
            if len(heap) < max_per_kind:
                heapq.heappush(heap, item)
            else:
                heapq.heappushpop(heap, item)
                dropped[0] += 1

    player: Player | None = None
    for part in parts:
        check_part(part, source)
        if player is None:
            settings = PipelineSettings(
                period_ns=part.streams["pt_ct"].period_ns if "pt_ct" in part.streams else PipelineSettings.period_ns,
                detector=DetectorSettings(thresholds=thresholds),
                auto_recalibrate=False,
                keep_windows=False,
            )
            player = Player(MonitorPipeline(settings), on_outputs=keep, keep_arrays=False)
        player.feed(part)
    if player is None:
        raise PhidError(f"{source}: no sensor data")
    try:
        player.finish()
        health = player.pipeline.health
    finally:
        player.pipeline.close()
    windows = sorted([w for heap in kept.values() for _, _, w in heap] + unusable, key=lambda w: w.event.inception_ns)
    notes = []
    if dropped[0]:
        notes.append(f"{source}: {dropped[0]} smaller disturbance(s) left out: the {max_per_kind} largest of each kind")
    out, problems = _window_scenarios(
        windows, health, source, thresholds, float(parts.metadata.get(MEASUREMENT_WINDOW_KEY, 0.0)), notes
    )
    if not windows:
        raise PhidError(
            f"{source}: no scenario markers and no disturbance found (no fault, torque step or voltage step)"
        )
    return out, problems + parts.warnings
