"""An in-memory recording: the four sensor streams plus the scenario markers.

This is what every bag, MCAP file and CSV import turns into, and what the
writers turn back into messages. A stream holds integer-nanosecond stamps and
one float64 array per channel; it may contain gaps (a new block starts at each).
"""

from __future__ import annotations

import heapq
import itertools
import math
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import BagError
from phid_ros.io.msg_schemas import typestore
from phid_ros.io.topics import (
    ALL_STREAMS_BY_NAME,
    DEFAULT_NAMESPACE,
    RECORDER_STREAMS,
    SCENARIO_MSGTYPE,
    SCENARIO_TOPIC,
    STREAMS,
    StreamSpec,
    topic_for,
)
from phid_ros.model.conventions import NS, split_stamp, stamp_ns

STREAM_NAMES = tuple(s.name for s in STREAMS)
DEFAULT_BLOCK_SIZE = 100  # 100 ms blocks at 1 kHz: 10 messages/s per stream


@dataclass
class StreamSamples:
    t_ns: NDArray[np.int64]
    period_ns: int
    channels: dict[str, NDArray[np.float64]]
    # as recorded (bags only): the sample index where each message starts and the message's
    # position in the file, so a replay feeds messages in recording order even when the
    # stamps jump (a stamp order would hide a clock that went back)
    msg_offsets: NDArray[np.int64] | None = None
    msg_seq: NDArray[np.int64] | None = None

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


# metadata key: the window (s) the samples were measured over, when an importer knows it (the
# one-cycle DFT of COMTRADE waveforms); stage 3 leaves that much out around each switching
MEASUREMENT_WINDOW_KEY = "measurement_window_s"


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
    regulator: str = ""  # who held the field in the test: "avr", "manual", or "" (not said)
    # the size of the test's reference step (pu of the reference, + and back), where the test sheet says
    reference_step: float | None = None


# channels the recorder never carried (a trend log has no rotor angle), comma-separated: the
# online pipeline judges the others, and an absent channel is not a dead one
NOT_RECORDED_KEY = "not_recorded"


def not_recorded(metadata: Mapping[str, str]) -> frozenset[str]:
    return frozenset(c for c in metadata.get(NOT_RECORDED_KEY, "").split(",") if c)


# what 1 pu of the recorded field quantities is in the recorder's units (a map's ``base``, or the
# import's no-load calibration): the field winding's resistance is then said in ohms
FIELD_BASES_KEY = "field_bases"


@dataclass(frozen=True)
class FieldBases:
    """Volts per pu of the recorded E_fd and amperes per pu of the recorded I_fd (None: recorded in
    per unit, or not recorded), as a recording's metadata carries them (``v_f=74 V;i_fd=725 A``)."""

    volts: float | None = None
    amperes: float | None = None

    def text(self) -> str:
        parts = [f"v_f={self.volts!r} V"] if self.volts is not None else []
        return ";".join([*parts, *([f"i_fd={self.amperes!r} A"] if self.amperes is not None else [])])

    @property
    def ohms_per_unit(self) -> float | None:
        """Ohms per unit of the recorded U_f per I_f, where both are recorded in volts and amperes."""
        return None if self.volts is None or self.amperes is None else self.volts / self.amperes


def field_bases(metadata: Mapping[str, str]) -> FieldBases | None:
    """The recording's field bases, or None where its metadata holds none (or holds them unreadably:
    a figure in ohms is then not said, never said wrong)."""
    text = metadata.get(FIELD_BASES_KEY)
    if not text:
        return None
    got: dict[str, float] = {}
    for part in text.split(";"):
        m = re.fullmatch(r"(v_f|i_fd)=([0-9.eE+-]+) (V|A)", part.strip())
        if m is None or (m[1] == "v_f") != (m[3] == "V"):
            return None
        value = float(m[2])
        if not (math.isfinite(value) and value > 0):
            return None
        got[m[1]] = value
    return FieldBases(got.get("v_f"), got.get("i_fd"))


# a field import's columns no channel map named (a regulator's output, a status word), comma-separated:
# recorded, left behind by the import, and said so
NOT_IMPORTED_KEY = "not_imported"


# who holds the field in a test: the voltage regulator (AVR), the AVR with its stabiliser on
# (avr+pss: where the stabiliser's output is not recorded, its effect is what identifies it), or a
# field-current regulator (manual, the AVR not in the loop). A scenario marker carries it in its
# description, "regulator: manual".
STABILISER_ON = "avr+pss"
REGULATORS = ("avr", STABILISER_ON, "manual")
_REGULATOR_TAG = re.compile(r"(?:^|; )regulator: (avr\+pss|avr|manual)$")


# the test sheet's reference step travels the same way, "reference step: 0.05", before the regulator
_REFERENCE_TAG = re.compile(r"(?:^|; )reference step: ([0-9.eE+-]+)(?=$|; regulator: )")


def with_test_sheet(description: str, regulator: str, reference_step: float | None = None) -> str:
    """A marker's description with what the test sheet says of the scenario at its end: the
    reference step's size, then who held the field."""
    tags = ([f"reference step: {reference_step!r}"] if reference_step is not None else []) + (
        [f"regulator: {regulator}"] if regulator else []
    )
    return "; ".join([description, *tags] if description else tags)


def regulator_in(description: str) -> str:
    """The regulator a marker's description says, or ""."""
    m = _REGULATOR_TAG.search(description)
    return m.group(1) if m else ""


def reference_step_in(description: str) -> float | None:
    """The reference step a marker's description says, or None."""
    m = _REFERENCE_TAG.search(description)
    return float(m.group(1)) if m else None


@dataclass
class Recording:
    streams: dict[str, StreamSamples]
    scenarios: list[ScenarioInfo] = field(default_factory=list)
    metadata: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)  # what the reader noticed (a truncated file, ...)

    def sensor_streams(self) -> dict[str, StreamSamples]:
        """The sensor streams (the online pipeline's), without a recorder's own."""
        return {name: s for name, s in self.streams.items() if name in STREAM_NAMES}

    def recorder_streams(self) -> dict[str, StreamSamples]:
        """A recorder's own streams (:data:`~phid_ros.io.topics.RECORDER_STREAMS`)."""
        return {name: s for name, s in self.streams.items() if name not in STREAM_NAMES}

    @property
    def f_nominal_hz(self) -> float:
        return float(self.metadata.get("f_nominal_hz", 50.0))

    def span_ns(self) -> tuple[int, int]:
        starts = [int(s.t_ns[0]) for s in self.streams.values() if len(s)]
        ends = [int(s.t_ns[-1]) for s in self.streams.values() if len(s)]
        if not starts:
            return 0, 0
        return min(starts), max(ends)


def describe_span(rec: Recording) -> str:
    """How much a reader got: per stream, samples and seconds (for a truncation warning)."""
    parts = [
        f"{name} {len(s)} samples ({(int(s.t_ns[-1]) - int(s.t_ns[0])) / NS:.1f} s)"
        for name, s in rec.streams.items()
        if len(s)
    ]
    return "read " + ", ".join(parts)


# -- time stamps -------------------------------------------------------------
def ns_to_time(ns: int) -> Any:  # rosbags' generated message classes: no static type
    store = typestore()
    sec, nanosec = split_stamp(ns)
    return store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


def _header(stamp_ns: int) -> Any:
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
    """(log time ns, topic, msgtype, message) in log-time order, as a list (see :func:`iter_recording_messages`)."""
    return list(iter_recording_messages(rec, block_size=block_size, namespace=namespace))


def iter_recording_messages(
    rec: Recording, *, block_size: int = DEFAULT_BLOCK_SIZE, namespace: str = DEFAULT_NAMESPACE
) -> Iterator[tuple[int, str, str, object]]:
    """(log time ns, topic, msgtype, message) in log-time order, made as they are taken.

    A block is logged at the stamp of its last sample, when a sensor node
    would publish it; a scenario marker at the start of its window. Messages of equal log time
    keep the order of the streams, then the markers'. Why made one at a time: a day of PMU
    reports is 170 000 messages, 190 MB as a list beside the samples they view.
    """
    store = typestore()
    streams: list[Iterator[tuple[int, str, str, object]]] = []
    in_order = True
    for spec in (*STREAMS, *RECORDER_STREAMS):
        stream = rec.streams.get(spec.name)
        if stream is None:
            continue
        bounds = block_bounds(stream.t_ns, stream.period_ns, block_size)
        ends = np.array([int(stream.t_ns[b - 1]) for _, b in bounds], dtype=np.int64)
        in_order &= bool(np.all(np.diff(ends) >= 0))  # a clock that jumps back: one sort of them all
        streams.append(_stream_messages(stream, spec, store, topic_for(spec.name, namespace), bounds))
    marker_cls = store.types[SCENARIO_MSGTYPE]
    markers = []
    for sc in rec.scenarios:
        msg = marker_cls(
            header=_header(sc.start_ns),
            name=sc.name,
            kind=sc.kind,
            role=sc.role,
            generator_damping=sc.generator_damping,
            magnitude=float(sc.magnitude),
            start=ns_to_time(sc.start_ns),
            event=ns_to_time(sc.event_ns),
            clearing=ns_to_time(sc.clearing_ns),
            end=ns_to_time(sc.end_ns),
            description=with_test_sheet(sc.description, sc.regulator, sc.reference_step),
        )
        markers.append((sc.start_ns, SCENARIO_TOPIC, SCENARIO_MSGTYPE, msg))
    markers.sort(key=lambda item: item[0])
    if in_order:  # heapq.merge keeps equal keys in the order of its inputs: the stable sort's order
        yield from heapq.merge(*streams, markers, key=lambda item: item[0])
    else:
        yield from sorted(itertools.chain(*streams, markers), key=lambda item: item[0])


def _stream_messages(
    stream: StreamSamples, spec: StreamSpec, store: Any, topic: str, bounds: list[tuple[int, int]]
) -> Iterator[tuple[int, str, str, object]]:
    cls = store.types[spec.msgtype]
    period_s = stream.period_ns / NS
    for a, b in bounds:
        arrays = {c: np.ascontiguousarray(stream.channels[c][a:b]) for c in spec.channels}
        msg = cls(header=_header(int(stream.t_ns[a])), sample_period=period_s, **arrays)
        yield int(stream.t_ns[b - 1]), topic, spec.msgtype, msg


# -- messages -> recording ---------------------------------------------------
def stream_of_topic(topic: str) -> str | None:
    """The stream a topic carries (by its last name component), or None."""
    last = topic.rstrip("/").rsplit("/", 1)[-1]
    return last if last in ALL_STREAMS_BY_NAME else None


@dataclass
class _Group:
    order: NDArray[np.int64]  # message index within its stream, one per row
    t0_ns: NDArray[np.int64]
    period_ns: NDArray[np.int64]
    values: list[NDArray[np.float64]]  # per channel, (rows, n)
    seq: NDArray[np.int64]  # message position in the whole file, one per row


class _Assembler:
    """Collects decoded blocks per stream and checks them; shared by the object and raw paths.

    Blocks arrive in groups of equal length (one row per message) so that a whole
    bag assembles with a few vectorised operations, not one per message.
    """

    def __init__(self, source: str) -> None:
        self.source = source
        self.groups: dict[str, list[_Group]] = {}
        self.topics: dict[str, str] = {}
        self.scenarios: list[ScenarioInfo] = []

    def add_group(
        self,
        stream: str,
        topic: str,
        order: NDArray[np.int64],
        t0_ns: NDArray[np.int64],
        period_s: NDArray[np.float64],
        values: list[NDArray[np.float64]],
        seq: NDArray[np.int64] | None = None,
    ) -> None:
        self.topics.setdefault(stream, topic)
        period_ns = np.rint(np.asarray(period_s, dtype=np.float64) * NS)
        bad = ~(period_ns > 0)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise BagError(
                f"{self.source}: {topic} message {int(order[i])} has sample_period {period_s[i]}, must be > 0"
            )
        self.groups.setdefault(stream, []).append(
            _Group(
                np.asarray(order, np.int64),
                np.asarray(t0_ns, np.int64),
                period_ns.astype(np.int64),
                values,
                np.asarray(order if seq is None else seq, np.int64),
            )
        )

    def add_message(
        self,
        stream: str,
        topic: str,
        index: int,
        t0_ns: int,
        period_s: float,
        arrays: list[NDArray[np.float64]],
        seq: int | None = None,
    ) -> None:
        lengths = {len(a) for a in arrays}
        if len(lengths) != 1:
            raise BagError(f"{self.source}: {topic} message {index} has arrays of unequal length {sorted(lengths)}")
        self.add_group(
            stream,
            topic,
            np.array([index]),
            np.array([t0_ns]),
            np.array([period_s]),
            [np.asarray(a, np.float64)[None, :] for a in arrays],
            np.array([index if seq is None else seq]),
        )

    def _stream(self, name: str) -> StreamSamples:
        groups = self.groups[name]
        spec = ALL_STREAMS_BY_NAME[name]
        order = np.concatenate([g.order for g in groups])
        seq = np.concatenate([g.seq for g in groups])
        periods = np.concatenate([g.period_ns for g in groups])
        lengths = np.concatenate([np.full(len(g.order), g.values[0].shape[1]) for g in groups])
        rank = np.argsort(order, kind="stable")
        first = int(periods[rank[0]])
        changed = np.flatnonzero(periods[rank] != first)
        if changed.size:
            k = rank[changed[0]]
            raise BagError(
                f"{self.source}: {self.topics[name]} changes sample period from {first} ns "
                f"to {int(periods[k])} ns at message {int(order[k])}"
            )
        slot = np.empty(len(order), dtype=np.int64)  # each message's place in the stream
        slot[rank] = np.arange(len(order))
        offsets = np.concatenate(([0], np.cumsum(lengths[rank])))
        total = int(offsets[-1])
        t_ns = np.empty(total, dtype=np.int64)
        channels = {c: np.empty(total, dtype=np.float64) for c in spec.channels}
        start = 0
        for g in groups:
            k, n = len(g.order), g.values[0].shape[1]
            places = slot[start : start + k]
            start += k
            if not k:
                continue
            step = np.arange(n, dtype=np.int64) * first
            if places[-1] - places[0] == k - 1 and np.all(np.diff(places) == 1):
                # a run: its messages are neighbours in the stream, one copy per channel, through
                # (messages, n) views (the group's arrays are strided views into the messages'
                # bytes; a reshape of them would copy everything once more)
                o0 = int(offsets[places[0]])
                np.add(g.t0_ns[:, None], step, out=t_ns[o0 : o0 + k * n].reshape(k, n))
                for c, v in zip(spec.channels, g.values):
                    channels[c][o0 : o0 + k * n].reshape(k, n)[...] = v
            else:  # single messages between runs: scattered by their samples' places
                at = offsets[places][:, None] + np.arange(n, dtype=np.int64)
                t_ns[at] = g.t0_ns[:, None] + step
                for c, v in zip(spec.channels, g.values):
                    channels[c][at] = v
        return StreamSamples(t_ns, first, channels, msg_offsets=offsets[:-1].astype(np.int64), msg_seq=seq[rank])

    def finish(self, required: Iterable[str], metadata: dict[str, str] | None) -> Recording:
        missing = [s for s in required if not self.groups.get(s)]
        if missing:
            present = ", ".join(sorted(self.groups)) or "none"
            raise BagError(f"{self.source}: no messages on the sensor stream(s) {missing} (streams present: {present})")
        streams = {name: self._stream(name) for name in self.groups}
        return Recording(streams=streams, scenarios=self.scenarios, metadata=dict(metadata or {}))


def _check_type(source: str, topic: str, msgtype: str, expected: str) -> None:
    if msgtype != expected:
        raise BagError(f"{source}: topic {topic} has type {msgtype}, expected {expected}")


def expected_type(topic: str) -> str | None:
    """The message type one of our topics must carry; None for topics that are not ours."""
    if topic == SCENARIO_TOPIC:
        return SCENARIO_MSGTYPE
    name = stream_of_topic(topic)
    return ALL_STREAMS_BY_NAME[name].msgtype if name else None


def is_phid_topic(topic: str) -> bool:
    """True for the topics this package reads (sensor streams and scenario markers)."""
    return topic == SCENARIO_TOPIC or stream_of_topic(topic) is not None


def recording_from_messages(
    items: Iterable[tuple[str, str, Any]],
    *,
    source: str,
    metadata: dict[str, str] | None = None,
    required: Iterable[str] = STREAM_NAMES,
) -> Recording:
    """Assemble a recording from (topic, msgtype, message object); ``source`` names the file in errors."""
    asm = _Assembler(source)
    counts: dict[str, int] = {}
    for seq, (topic, msgtype, msg) in enumerate(items):
        if topic == SCENARIO_TOPIC:
            _check_type(source, topic, msgtype, SCENARIO_MSGTYPE)
            asm.scenarios.append(scenario_from_message(msg))
            continue
        name = stream_of_topic(topic)
        if name is None:
            continue  # other plant data in the same bag is not ours to judge
        spec = ALL_STREAMS_BY_NAME[name]
        _check_type(source, topic, msgtype, spec.msgtype)
        index = counts.get(name, 0)
        counts[name] = index + 1
        arrays = [np.asarray(getattr(msg, c), dtype=np.float64) for c in spec.channels]
        asm.add_message(name, topic, index, stamp_ns(msg.header.stamp), msg.sample_period, arrays, seq)
    return asm.finish(required, metadata)


def recording_from_raw(
    items: Iterable[tuple],
    *,
    source: str,
    metadata: dict[str, str] | None = None,
    required: Iterable[str] = STREAM_NAMES,
) -> Recording:
    """Assemble a recording from raw CDR (topic, msgtype, bytes), decoding sensor blocks vectorised.

    An item may carry its position in the file as a fourth field, and its payload may then be a
    run of equally long messages (:func:`phid_ros.io.bags.mcap_raw.iter_message_runs`); without it the
    items are in file order.
    """
    from phid_ros.io.bags.cdr_blocks import decode_group, stack_by_length

    store = typestore()
    raws: dict[str, list] = {}
    seqs: dict[str, list] = {}
    topics: dict[str, str] = {}
    markers: list[tuple[int, bytes, str, str]] = []

    def deserialize(raw: bytes, msgtype: str, topic: str) -> Any:
        try:
            return store.deserialize_cdr(raw, msgtype)
        except Exception as exc:  # deserialisers raise struct/index/value errors on bad bytes
            raise BagError(f"{source}: corrupt message on {topic}: {exc}") from exc

    asm = _Assembler(source)
    # (topic, type) -> its payload list and its positions list, or None for topics not ours
    routes: dict[tuple[str, str], tuple[list, list] | None] = {}
    for position, item in enumerate(items):
        topic, msgtype, raw = item[0], item[1], item[2]
        where = item[3] if len(item) > 3 else position
        key = (topic, msgtype)
        if key not in routes:
            dest = _route(source, topic, msgtype, raws, topics)
            routes[key] = None if dest is None else (dest, seqs.setdefault(stream_of_topic(topic) or "", []))
        route = routes[key]
        if route is not None:
            route[0].append(raw)
            route[1].append(where)
        elif topic == SCENARIO_TOPIC:
            if isinstance(raw, np.ndarray):  # a run of markers: each one on its own
                markers += [(int(w), bytes(r), msgtype, topic) for r, w in zip(raw, np.asarray(where))]
            else:
                markers.append((where, bytes(raw), msgtype, topic))
    # markers in file order, whichever way they came
    asm.scenarios += [scenario_from_message(deserialize(*m[1:])) for m in sorted(markers, key=lambda m: m[0])]
    if not raws and not asm.scenarios:
        present = ", ".join(sorted({t for t, _ in routes})) or "none"
        raise BagError(f"{source}: none of the phid sensor topics found (topics present: {present})")
    for name, msgs in raws.items():
        spec = ALL_STREAMS_BY_NAME[name]
        groups, seq_of = stack_by_length(msgs, seqs[name])
        rest: list[tuple[int, bytes]] = []
        for rows, idx in groups:
            dec = decode_group(rows, idx, None, len(spec.channels))
            if dec is None:
                rest += [(int(i), bytes(r)) for i, r in zip(idx, rows)]
                continue
            asm.add_group(name, topics[name], dec.order, dec.t0_ns, dec.period_s, dec.values, seq_of[dec.order])
        for i, raw in rest:
            msg = deserialize(raw, spec.msgtype, topics[name])
            arrays = [np.asarray(getattr(msg, c), dtype=np.float64) for c in spec.channels]
            asm.add_message(
                name,
                topics[name],
                i,
                stamp_ns(msg.header.stamp),
                msg.sample_period,
                arrays,
                int(seq_of[i]),
            )
    return asm.finish(required, metadata)


def checked_payloads(messages: Iterable[tuple], source: str) -> Iterator[tuple]:
    """(topic, type, payload[, position]) from (topic, schema name, encoding, payload[, position]):
    our topics must be cdr and known. The payload may be a run (:data:`phid_ros.io.bags.mcap_raw.Positioned`).

    Foreign topics pass through unchecked (they are counted, then ignored).
    """
    store = typestore()
    checked: set[tuple[str, str, str]] = set()  # a (topic, type, encoding) is judged once, not per message
    for item in messages:
        topic, schema, encoding = item[0], item[1], item[2]
        if (topic, schema, encoding) not in checked:
            if not is_phid_topic(topic):
                yield (topic, schema, *item[3:])
                continue
            if encoding != "cdr" or not schema:
                raise BagError(f"{source}: topic {topic} is not cdr-encoded ROS 2 data")
            _check_type(source, topic, schema, expected_type(topic))  # type: ignore[arg-type]
            if schema not in store.types:
                raise BagError(f"{source}: topic {topic} has unknown message type {schema}")
            checked.add((topic, schema, encoding))
        yield (topic, schema, *item[3:])


def _route(source: str, topic: str, msgtype: str, raws: dict[str, list], topics: dict[str, str]) -> list | None:
    """The payload list of a sensor topic (after checking its type); None for others."""
    if topic == SCENARIO_TOPIC:
        _check_type(source, topic, msgtype, SCENARIO_MSGTYPE)
        return None
    name = stream_of_topic(topic)
    if name is None:
        return None
    _check_type(source, topic, msgtype, ALL_STREAMS_BY_NAME[name].msgtype)
    if topics.setdefault(name, topic) != topic:
        raise BagError(f"{source}: stream {name} arrives on two topics, {topics[name]} and {topic}")
    return raws.setdefault(name, [])


def scenario_from_message(msg: Any) -> ScenarioInfo:
    """A ScenarioMarker message (from a bag, or as a node receives it) as the recording's marker."""
    m = msg
    return ScenarioInfo(
        name=m.name,
        kind=m.kind,
        role=m.role,
        generator_damping=bool(m.generator_damping),
        magnitude=float(m.magnitude),
        start_ns=stamp_ns(m.start),
        event_ns=stamp_ns(m.event),
        clearing_ns=stamp_ns(m.clearing),
        end_ns=stamp_ns(m.end),
        description=m.description,
        regulator=regulator_in(m.description),
        reference_step=reference_step_in(m.description),
    )
