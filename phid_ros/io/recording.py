"""An in-memory recording: the four sensor streams plus the scenario markers.

This is what every bag, MCAP file and CSV import turns into, and what the
writers turn back into messages. A stream holds integer-nanosecond stamps and
one float64 array per channel; it may contain gaps (a new block starts at each).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import BagError
from phid_ros.io.msg_schemas import typestore
from phid_ros.io.topics import (
    DEFAULT_NAMESPACE,
    SCENARIO_MSGTYPE,
    SCENARIO_TOPIC,
    STREAMS,
    STREAMS_BY_NAME,
    topic_for,
)

NS = 1_000_000_000
DEFAULT_BLOCK_SIZE = 50  # 50 ms blocks at 1 kHz: 20 messages/s per stream


@dataclass
class StreamSamples:
    t_ns: NDArray[np.int64]
    period_ns: int
    channels: dict[str, NDArray[np.float64]]

    def __post_init__(self) -> None:
        self.t_ns = np.asarray(self.t_ns, dtype=np.int64)
        if self.t_ns.ndim != 1:
            raise ValueError("t_ns must be one-dimensional")
        if self.period_ns <= 0:
            raise ValueError(f"period_ns must be positive, got {self.period_ns}")
        for name, values in self.channels.items():
            arr = np.asarray(values, dtype=np.float64)
            if arr.shape != self.t_ns.shape:
                raise ValueError(f"channel {name} has {arr.shape[0]} samples, stamps have {self.t_ns.shape[0]}")
            self.channels[name] = arr

    def __len__(self) -> int:
        return int(self.t_ns.shape[0])


@dataclass(frozen=True)
class ScenarioInfo:
    name: str
    kind: str = "unknown"
    role: str = "identify"
    generator_damping: bool = True
    magnitude: float = math.nan
    start_ns: int = 0
    event_ns: int = 0  # 0: unknown
    clearing_ns: int = 0  # 0: not a fault
    end_ns: int = 0
    description: str = ""


@dataclass
class Recording:
    streams: dict[str, StreamSamples]
    scenarios: list[ScenarioInfo] = field(default_factory=list)
    metadata: dict[str, str] = field(default_factory=dict)

    @property
    def f_nominal_hz(self) -> float:
        return float(self.metadata.get("f_nominal_hz", 50.0))

    def span_ns(self) -> tuple[int, int]:
        starts = [int(s.t_ns[0]) for s in self.streams.values() if len(s)]
        ends = [int(s.t_ns[-1]) for s in self.streams.values() if len(s)]
        if not starts:
            return 0, 0
        return min(starts), max(ends)


# -- time stamps -------------------------------------------------------------
def ns_to_time(ns: int) -> object:
    store = typestore()
    sec, nanosec = divmod(int(ns), NS)
    return store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


def time_to_ns(t: object) -> int:
    return int(t.sec) * NS + int(t.nanosec)  # type: ignore[attr-defined]


def _header(stamp_ns: int) -> object:
    return typestore().types["std_msgs/msg/Header"](stamp=ns_to_time(stamp_ns), frame_id="generator")


# -- recording -> messages ---------------------------------------------------
def block_bounds(t_ns: NDArray[np.int64], period_ns: int, block_size: int) -> list[tuple[int, int]]:
    """[start, stop) index pairs: blocks of at most ``block_size`` uniform samples, split at gaps."""
    if block_size < 1:
        raise ValueError("block_size must be at least 1")
    n = len(t_ns)
    breaks = np.flatnonzero(np.diff(t_ns) != period_ns) + 1
    edges = np.concatenate(([0], breaks, [n]))
    out: list[tuple[int, int]] = []
    for a, b in zip(edges[:-1], edges[1:]):
        out.extend((int(s), int(min(s + block_size, b))) for s in range(int(a), int(b), block_size))
    return out


def recording_messages(
    rec: Recording, *, block_size: int = DEFAULT_BLOCK_SIZE, namespace: str = DEFAULT_NAMESPACE
) -> list[tuple[int, str, str, object]]:
    """(log time ns, topic, msgtype, message) in log-time order.

    A block is logged at the stamp of its last sample, when a sensor node
    would publish it; a scenario marker at the start of its window.
    """
    store = typestore()
    out: list[tuple[int, str, str, object]] = []
    for spec in STREAMS:
        stream = rec.streams.get(spec.name)
        if stream is None:
            continue
        cls = store.types[spec.msgtype]
        period_s = stream.period_ns / NS
        topic = topic_for(spec.name, namespace)
        for a, b in block_bounds(stream.t_ns, stream.period_ns, block_size):
            arrays = {c: np.ascontiguousarray(stream.channels[c][a:b]) for c in spec.channels}
            msg = cls(header=_header(int(stream.t_ns[a])), sample_period=period_s, **arrays)
            out.append((int(stream.t_ns[b - 1]), topic, spec.msgtype, msg))
    marker_cls = store.types[SCENARIO_MSGTYPE]
    for sc in rec.scenarios:
        msg = marker_cls(
            header=_header(sc.start_ns), name=sc.name, kind=sc.kind, role=sc.role,
            generator_damping=sc.generator_damping, magnitude=float(sc.magnitude),
            start=ns_to_time(sc.start_ns), event=ns_to_time(sc.event_ns),
            clearing=ns_to_time(sc.clearing_ns), end=ns_to_time(sc.end_ns), description=sc.description,
        )
        out.append((sc.start_ns, SCENARIO_TOPIC, SCENARIO_MSGTYPE, msg))
    out.sort(key=lambda item: item[0])
    return out


# -- messages -> recording ---------------------------------------------------
def stream_of_topic(topic: str) -> str | None:
    """The stream a topic carries (by its last name component), or None."""
    last = topic.rstrip("/").rsplit("/", 1)[-1]
    return last if last in STREAMS_BY_NAME else None


def is_phid_topic(topic: str) -> bool:
    """True for the topics this package reads (sensor streams and scenario markers)."""
    return topic == SCENARIO_TOPIC or stream_of_topic(topic) is not None


def recording_from_messages(
    items: Iterable[tuple[str, str, object]], *, source: str, metadata: dict[str, str] | None = None,
    required: Iterable[str] = tuple(s.name for s in STREAMS),
) -> Recording:
    """Assemble a recording from (topic, msgtype, message); ``source`` names the file in errors."""
    parts: dict[str, dict[str, list[NDArray[np.float64]]]] = {s.name: {c: [] for c in s.channels} for s in STREAMS}
    stamps: dict[str, list[NDArray[np.int64]]] = {s.name: [] for s in STREAMS}
    periods: dict[str, int] = {}
    scenarios: list[ScenarioInfo] = []
    counts: dict[str, int] = {}
    for topic, msgtype, msg in items:
        if topic == SCENARIO_TOPIC:
            if msgtype != SCENARIO_MSGTYPE:
                raise BagError(f"{source}: topic {topic} has type {msgtype}, expected {SCENARIO_MSGTYPE}")
            scenarios.append(_scenario_from_msg(msg))
            continue
        name = stream_of_topic(topic)
        if name is None:
            continue  # other plant data in the same bag is not ours to judge
        spec = STREAMS_BY_NAME[name]
        if msgtype != spec.msgtype:
            raise BagError(f"{source}: topic {topic} has type {msgtype}, expected {spec.msgtype}")
        index = counts.get(name, 0)
        counts[name] = index + 1
        period_ns = int(round(float(msg.sample_period) * NS))  # type: ignore[attr-defined]
        if period_ns <= 0:
            raise BagError(f"{source}: {topic} message {index} has sample_period {msg.sample_period}, must be > 0")  # type: ignore[attr-defined]
        if periods.setdefault(name, period_ns) != period_ns:
            raise BagError(f"{source}: {topic} changes sample period from {periods[name]} ns to {period_ns} ns at message {index}")
        arrays = [np.asarray(getattr(msg, c), dtype=np.float64) for c in spec.channels]
        lengths = {len(a) for a in arrays}
        if len(lengths) != 1:
            raise BagError(f"{source}: {topic} message {index} has arrays of unequal length {sorted(lengths)}")
        n = lengths.pop()
        t0 = time_to_ns(msg.header.stamp)  # type: ignore[attr-defined]
        stamps[name].append(t0 + np.arange(n, dtype=np.int64) * period_ns)
        for c, a in zip(spec.channels, arrays):
            parts[name][c].append(a)
    missing = [s for s in required if not stamps.get(s)]
    if missing:
        present = ", ".join(sorted(counts)) or "none"
        raise BagError(f"{source}: no messages on the sensor stream(s) {missing} (streams present: {present})")
    streams = {
        name: StreamSamples(np.concatenate(stamps[name]), periods[name],
                            {c: np.concatenate(v) for c, v in parts[name].items()})
        for name in stamps if stamps[name]
    }
    return Recording(streams=streams, scenarios=scenarios, metadata=dict(metadata or {}))


def _scenario_from_msg(msg: object) -> ScenarioInfo:
    m = msg
    return ScenarioInfo(
        name=m.name, kind=m.kind, role=m.role, generator_damping=bool(m.generator_damping),  # type: ignore[attr-defined]
        magnitude=float(m.magnitude), start_ns=time_to_ns(m.start), event_ns=time_to_ns(m.event),  # type: ignore[attr-defined]
        clearing_ns=time_to_ns(m.clearing), end_ns=time_to_ns(m.end), description=m.description,  # type: ignore[attr-defined]
    )


def iter_channel_arrays(rec: Recording) -> Iterator[tuple[str, str, NDArray[np.float64]]]:
    for sname, stream in rec.streams.items():
        for cname, values in stream.channels.items():
            yield sname, cname, values
