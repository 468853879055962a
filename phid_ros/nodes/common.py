"""Wiring shared by the phid nodes: QoS, parameter declaration from the tunables table, types.

Only the nodes import rclpy; everything they do is in phid_ros.stream.
"""

from __future__ import annotations

import array
import contextlib
import math
import signal
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

from phid_ros.cluster import tune_malloc
from phid_ros.io.topics import OUTPUT_TOPICS, STREAMS
from phid_ros.stream.params import Tunable, validate


def sensor_qos(reliable: bool, depth: int) -> QoSProfile:
    """The sensor-data profile (best effort, volatile), with a queue sized for the stream rate:
    the profile's own depth of 5 drops blocks whenever a callback is late at playback rates."""
    profile = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else qos_profile_sensor_data.reliability,
        durability=qos_profile_sensor_data.durability,
    )
    return profile


def steady_timer(node: Node, period_s: float, callback: Any) -> Any:
    """A timer on the steady clock: work and publishing go on when a simulated /clock stops
    (a bag that ended), which a timer on the node's clock would not."""
    return node.create_timer(period_s, callback, clock=Clock(clock_type=ClockType.STEADY_TIME))


def byte_level(value: int) -> bytes:
    """diagnostic_msgs' ``byte`` field as rclpy wants it."""
    return bytes([value])


def latched_qos() -> QoSProfile:
    """Transient local: a late subscriber gets the latest parameter set."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


def output_publisher(node: Any, key: str, qos: QoSProfile) -> Any:
    """A publisher of output ``key`` of phid_ros.io.topics.OUTPUT_TOPICS (its topic and type)."""
    topic, msgtype = OUTPUT_TOPICS[key]
    return node.create_publisher(node.types[msgtype], topic, qos)


def reliable_qos(depth: int = 50) -> QoSProfile:
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=ReliabilityPolicy.RELIABLE)


def declare(node: Node, table: tuple[Tunable, ...]) -> dict[str, Any]:
    """Declare every tunable with its descriptor; returns the values in force."""
    values = {}
    for t in table:
        d = ParameterDescriptor(description=t.description, read_only=not t.runtime)
        if t.type is float and t.low is not None:
            high = math.inf if t.high is None else float(t.high)
            d.floating_point_range = [FloatingPointRange(from_value=float(t.low), to_value=high, step=0.0)]
        elif t.type is int and t.low is not None and t.high is not None:
            d.integer_range = [IntegerRange(from_value=int(t.low), to_value=int(t.high), step=1)]
        values[t.name] = node.declare_parameter(t.name, t.default, d).value
        refused = validate(table, t.name, values[t.name], running=False)
        if refused:
            raise ValueError(f"parameter {refused}")
    return values


def on_set(table: tuple[Tunable, ...], apply: Any) -> Any:
    """A parameter callback that validates each change (keeping the old value on refusal)."""

    def callback(params: list[Any]) -> SetParametersResult:
        for p in params:
            reason = validate(table, p.name, p.value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        for p in params:
            apply(p.name, p.value)
        return SetParametersResult(successful=True)

    return callback


def float_seq(a: Any) -> array.array:
    """float64[] for rclpy: an array.array('d') is taken without per-element checks."""
    return array.array("d", np.ascontiguousarray(a, dtype=np.float64).tobytes())


def msg_types() -> dict[str, Any]:
    """Full type name -> rclpy message class, for phid_ros.stream.messages."""
    from builtin_interfaces.msg import Time
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from phid_msgs.msg import (
        DisturbanceEvent,
        EncoderBlock,
        EventWindow,
        ExcitationBlock,
        GeneratorParameters,
        HamiltonianState,
        PmuBlock,
        PtCtBlock,
        ScenarioMarker,
    )
    from std_msgs.msg import Header

    return {
        "builtin_interfaces/msg/Time": Time,
        "std_msgs/msg/Header": Header,
        "diagnostic_msgs/msg/DiagnosticArray": DiagnosticArray,
        "diagnostic_msgs/msg/DiagnosticStatus": DiagnosticStatus,
        "diagnostic_msgs/msg/KeyValue": KeyValue,
        "phid_msgs/msg/DisturbanceEvent": DisturbanceEvent,
        "phid_msgs/msg/EncoderBlock": EncoderBlock,
        "phid_msgs/msg/EventWindow": EventWindow,
        "phid_msgs/msg/ExcitationBlock": ExcitationBlock,
        "phid_msgs/msg/GeneratorParameters": GeneratorParameters,
        "phid_msgs/msg/HamiltonianState": HamiltonianState,
        "phid_msgs/msg/PmuBlock": PmuBlock,
        "phid_msgs/msg/PtCtBlock": PtCtBlock,
        "phid_msgs/msg/ScenarioMarker": ScenarioMarker,
    }


def now_ns(node: Node) -> int:
    return int(node.get_clock().now().nanoseconds)


def subscribe_sensors(node: Any, on_data: Any = None) -> None:
    """Both nodes' sensor subscriptions: each block goes to ``node.pipeline.ingest_message``, the entry
    point phid replay feeds too; ``on_data`` (if given) hears that data arrived."""
    from phid_ros.stream import messages as m

    values = node.values
    qos = sensor_qos(values["reliable_qos"], values["queue_depth"])
    for spec in STREAMS:  # a stream's name is its topic, relative to the node's namespace

        def callback(msg: Any, stream: str = spec.name, channels: tuple[str, ...] = spec.channels) -> None:
            if on_data is not None:
                on_data()
            node.pipeline.ingest_message(  # a zero stamp is counted and dropped by the pipeline
                stream,
                m.stamp_ns(msg.header.stamp),
                m.seconds_to_ns(msg.sample_period),
                m.block_arrays(msg, channels),
                receive_ns=now_ns(node),
            )

        node.create_subscription(node.types[spec.msgtype], spec.name, callback, qos)
    node.get_logger().info(
        f"ready: {', '.join(s.name for s in STREAMS)} ({'reliable' if values['reliable_qos'] else 'best effort'}, "
        f"depth {values['queue_depth']})"
    )


def spin_until_shutdown(make_node: Any, args: list[str] | None) -> None:
    """The node skeleton of ros2/demos: init, spin, and a clean exit on Ctrl-C or external shutdown."""
    tune_malloc()  # as the CLI: the recalibration's arrays would fault their pages in at every run
    rclpy.init(args=args)
    node = make_node()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass  # asked to stop: leave quietly, the finally block cleans up
    finally:
        # Ctrl-C in a terminal reaches the node twice (the terminal signals the whole process group,
        # and ros2 launch forwards its own): the second must not cut the cleanup short (seen: a
        # KeyboardInterrupt inside destroy_node, "process has died" in the launch log)
        with _sigint_ignored():
            node.pipeline.close()
            node.destroy_node()
            rclpy.try_shutdown()


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    previous = _set_sigint(signal.SIG_IGN)
    try:
        yield
    finally:
        if previous is not None:
            _set_sigint(previous)


def _set_sigint(handler: Any) -> Any:
    """Install ``handler`` for SIGINT; the one replaced, or None when that cannot be done here (not the
    main thread). A SIGINT arriving during the switch makes Python raise "ignored due to race
    condition" once: the switch is tried again."""
    for _ in range(3):
        try:
            return signal.signal(signal.SIGINT, handler)
        except ValueError:
            return None
        except OSError:
            continue
    return None


class InputWatch:
    """Whether the sensor input has ended: no data for ``end_of_data_s`` of wall time since the
    last (a bag finished, a feed stopped). ``ended()`` is true once per stop."""

    def __init__(self) -> None:
        self._last = time.monotonic()
        self._done = True  # nothing owed before the first data

    def on_data(self) -> None:
        self._last, self._done = time.monotonic(), False

    def ended(self, after_s: float) -> bool:
        if self._done or time.monotonic() - self._last <= after_s:
            return False
        self._done = True
        return True
