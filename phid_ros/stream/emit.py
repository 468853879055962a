"""The pipeline's outputs as the messages on its output topics: one mapping for the nodes and replay.

``phid replay`` writes what the nodes publish, so both turn :class:`Outputs` into messages here
and nowhere else. Each message carries its topic key (``phid_ros.io.topics.OUTPUT_TOPICS``) and
the stream time it belongs to (a bag's log time; the nodes publish at once and ignore it). What
an operator should hear of (a window not published, a recalibration rejected, a drift alarm)
comes back as notes, which the nodes log and replay shows in its summary.

The usable-window policy, stated once: a window is published only when it is usable. An
``EventWindow`` message carries no usability, so the recalibration node stores every window it
receives; a window cut short by a clock jump or a ring buffer too short, published, would enter
a recalibration as if it were whole. The nodes always held this; replay wrote every window
until both came here (on the shipped bags every window is usable, so their bytes are unchanged).
"""

from __future__ import annotations

from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from typing import Any

from phid_ros.io.topics import OUTPUT_TOPICS
from phid_ros.stream import messages as m
from phid_ros.stream.detector import EventWindow
from phid_ros.stream.levels import Level
from phid_ros.stream.pipeline import Outputs

ALL_KEYS = frozenset(k for k in OUTPUT_TOPICS if k != "diagnostics")  # diagnostics go on a clock of their own


@dataclass(frozen=True)
class Published:
    """One message for output topic ``key``, stamped ``log_ns`` in stream time."""

    key: str
    log_ns: int
    message: Any


@dataclass
class Emitted:
    messages: list[Published] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def __iter__(self) -> Iterator[Published]:
        return iter(self.messages)


def publishable(w: EventWindow) -> bool:
    """The usable-window policy (see the module's text): only a usable window goes out."""
    return w.usable


def emit(
    types: m.Types,
    out: Outputs,
    keys: Collection[str] = ALL_KEYS,
    seq: m.Seq = m.numpy_seq,
    bools: m.Seq = m.numpy_bools,
) -> Emitted:
    """``out`` as messages for the output topics in ``keys`` (a node publishes its own few).

    ``types``, ``seq`` and ``bools`` are the message table's (see :mod:`phid_ros.stream.messages`):
    the rosbags typestore for a bag, rclpy's classes for the nodes.
    """
    unknown = set(keys) - ALL_KEYS
    if unknown:
        raise ValueError(f"emit: no output topic {sorted(unknown)} (known: {sorted(ALL_KEYS)})")
    done = Emitted()

    def add(key: str, log_ns: int, msg: Any) -> None:
        if key in keys:
            done.messages.append(Published(key, int(log_ns), msg))

    for e in out.events:
        add("events", e.inception_ns, m.event_message(types, e))
    for w in out.windows:
        if not publishable(w):
            done.notes.append(f"event {w.event.event_id} ({w.event.kind}) window not published, not usable: {w.reason}")
            continue
        if "windows" in keys:
            add("windows", int(w.t_ns[-1]) if len(w.t_ns) else w.event.inception_ns, m.window_message(types, w, seq))
    for r in out.recalibrations:
        msg = m.parameters_message(types, r, seq, bools)
        if msg is not None:
            add("parameters", r.stream_time_ns, msg)
        if "controls" in keys:
            for c in m.controls_messages(types, r, seq, bools):
                add("controls", r.stream_time_ns, c)
        if not r.accepted:
            done.notes.append(r.status)
    if "hamiltonian" in keys:
        for energy in out.energy:
            for t, msg in zip(energy.t_ns, m.hamiltonian_messages(types, energy)):
                add("hamiltonian", int(t), msg)
    for p in out.tracked:
        add("tracked_parameters", p.t_ns, m.tracked_message(types, p, seq, bools))
        done.notes += p.alarms
    for v in out.verdicts:
        add("model_validation", v.stream_time_ns, m.verdict_message(types, v, seq, bools))
        if v.level != Level.OK:
            done.notes.append(f"record on file {v.level}: {v.status}")
    return done
