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
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

from phid_ros.cluster import one_blas_thread, tune_malloc
from phid_ros.io.topics import OUTPUT_TOPICS, RECORDER_STREAMS, STREAMS
from phid_ros.stream.params import Tunable, apply, validate


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


def latched_qos(depth: int = 1) -> QoSProfile:
    """Transient local: a late subscriber gets the latest parameter set (the latest ``depth``
    messages: one per control system)."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


def reliable_qos(depth: int = 50) -> QoSProfile:
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=ReliabilityPolicy.RELIABLE)


def declare(node: Node, table: tuple[Tunable, ...]) -> dict[str, Any]:
    """Declare every tunable with its descriptor; returns the values in force. A start-up parameter
    is not read-only: it may be set while the node is unconfigured and takes effect on configure
    (``on_set`` refuses it from then until cleanup)."""
    values = {}
    for t in table:
        d = ParameterDescriptor(description=t.description, read_only=False)
        if not t.runtime:
            d.additional_constraints = "set while the node is unconfigured; it takes effect on configure"
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


def on_set(table: tuple[Tunable, ...], apply: Any, configured: Any = lambda: True) -> Any:
    """A parameter callback that validates each change (keeping the old value on refusal); a start-up
    parameter is refused while ``configured()``. ``apply`` hears each accepted change."""

    def callback(params: list[Any]) -> SetParametersResult:
        for p in params:
            reason = validate(table, p.name, p.value, running=configured())
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        for p in params:
            apply(p.name, p.value)
        return SetParametersResult(successful=True)

    return callback


SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


class MonitorNode(LifecycleNode):
    """A managed node, as robot_localization and nav2 run theirs: it starts unconfigured;
    configure builds the pipeline from the parameters and creates its topics and services;
    activate starts the timers and lets data in and outputs out; deactivate stops them (the
    pipeline and its memory stay); cleanup drops the pipeline (a start-up parameter may change
    then). With the ``autostart`` parameter (the default) it configures and activates itself.

    A subclass gives ``build()`` (the pipeline, publishers, subscriptions and services, each made
    with the methods below so that cleanup can take them down) and ``timer_periods()``; a
    run-time parameter change goes to the pipeline's settings (``apply_change``)."""

    def __init__(self, name: str, table: tuple[Tunable, ...]) -> None:
        super().__init__(name)
        self.table = table
        self.values = declare(self, table)
        self.types = msg_types()
        self.pipeline: Any = None
        self.active = False
        self.input = InputWatch()
        self._made: list[tuple[str, Any]] = []  # (kind, entity) made on configure
        self._timers: list[Any] = []
        self.add_on_set_parameters_callback(on_set(table, self._changed, lambda: self.pipeline is not None))
        if self.values["autostart"]:
            for step, name_ in ((self.trigger_configure, "configure"), (self.trigger_activate, "activate")):
                if step() != SUCCESS:
                    self.get_logger().error(f"autostart: {name_} failed; the node stays in its last state")
                    break

    # -- what a subclass gives -------------------------------------------------------------
    def build(self) -> None:
        raise NotImplementedError

    def timer_periods(self) -> list[tuple[float, Any]]:
        raise NotImplementedError

    def apply_change(self, name: str, value: Any) -> None:
        """A run-time change to the configured pipeline (already validated)."""
        self.pipeline.configure(apply(self.pipeline.settings, name, value))

    # -- made on configure, taken down on cleanup ---------------------------------------------
    def publisher(self, key: str, qos: QoSProfile) -> Any:
        """A lifecycle publisher of output ``key``: it sends only while the node is active."""
        topic, msgtype = OUTPUT_TOPICS[key]
        pub = self.create_lifecycle_publisher(self.types[msgtype], topic, qos)
        self._made.append(("publisher", pub))
        return pub

    def subscription(self, msgtype: Any, topic: str, callback: Any, qos: Any) -> Any:
        """A subscription whose messages are taken only while the node is active."""

        def when_active(msg: Any) -> None:
            if self.active:
                callback(msg)

        sub = self.create_subscription(msgtype, topic, when_active, qos)
        self._made.append(("subscription", sub))
        return sub

    def service(self, srv_type: Any, name: str, callback: Any) -> Any:
        def when_active(request: Any, response: Any) -> Any:
            if not self.active:
                response.success, response.message = False, "the node is not active (ros2 lifecycle set ... activate)"
                return response
            return callback(request, response)

        srv = self.create_service(srv_type, name, when_active)
        self._made.append(("service", srv))
        return srv

    # -- transitions ----------------------------------------------------------------------
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        # rclpy swallows an exception in a transition (it only returns ERROR): say it here
        try:
            self.values = {t.name: self.get_parameter(t.name).value for t in self.table}
            self.build()
        except Exception as exc:
            self.get_logger().error(f"configure failed: {exc}")
            self._take_down()
            return FAILURE
        self.get_logger().info("configured")
        return SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._timers = [steady_timer(self, period, callback) for period, callback in self.timer_periods()]
        self.input = InputWatch()
        self.active = True
        self.get_logger().info("active")
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        self._stop_timers()
        self.get_logger().info("inactive: inputs ignored, nothing published")
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._take_down()
        self.get_logger().info("unconfigured: the pipeline and its buffers dropped")
        return SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        self._take_down()
        return SUCCESS

    def _changed(self, name: str, value: Any) -> None:
        self.values[name] = value
        if self.pipeline is not None:
            self.apply_change(name, value)

    def _stop_timers(self) -> None:
        for t in self._timers:
            self.destroy_timer(t)
        self._timers = []

    def _take_down(self) -> None:
        """Everything configure made, in reverse; the pipeline closed (its store written)."""
        self.active = False
        self._stop_timers()
        for kind, entity in reversed(self._made):
            if kind == "publisher":
                self.destroy_lifecycle_publisher(entity)
            elif kind == "subscription":
                self.destroy_subscription(entity)
            else:
                self.destroy_service(entity)
        self._made = []
        if self.pipeline is not None:
            self.pipeline.close()
            self.pipeline = None


def float_seq(a: Any) -> array.array:
    """float64[] for rclpy: an array.array('d') is taken without per-element checks."""
    return array.array("d", np.ascontiguousarray(a, dtype=np.float64).tobytes())


def msg_types() -> dict[str, Any]:
    """Full type name -> rclpy message class, for phid_ros.stream.messages."""
    from builtin_interfaces.msg import Time
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from phid_msgs.msg import (
        ControlParameters,
        DisturbanceEvent,
        EncoderBlock,
        EventWindow,
        ExcitationBlock,
        FieldControllerBlock,
        GeneratorParameters,
        HamiltonianState,
        ModelValidation,
        PmuBlock,
        PtCtBlock,
        ScenarioMarker,
        SetPointBlock,
    )
    from std_msgs.msg import Header

    return {
        "builtin_interfaces/msg/Time": Time,
        "std_msgs/msg/Header": Header,
        "diagnostic_msgs/msg/DiagnosticArray": DiagnosticArray,
        "diagnostic_msgs/msg/DiagnosticStatus": DiagnosticStatus,
        "diagnostic_msgs/msg/KeyValue": KeyValue,
        "phid_msgs/msg/ControlParameters": ControlParameters,
        "phid_msgs/msg/DisturbanceEvent": DisturbanceEvent,
        "phid_msgs/msg/EncoderBlock": EncoderBlock,
        "phid_msgs/msg/EventWindow": EventWindow,
        "phid_msgs/msg/ExcitationBlock": ExcitationBlock,
        "phid_msgs/msg/FieldControllerBlock": FieldControllerBlock,
        "phid_msgs/msg/GeneratorParameters": GeneratorParameters,
        "phid_msgs/msg/HamiltonianState": HamiltonianState,
        "phid_msgs/msg/ModelValidation": ModelValidation,
        "phid_msgs/msg/PmuBlock": PmuBlock,
        "phid_msgs/msg/PtCtBlock": PtCtBlock,
        "phid_msgs/msg/ScenarioMarker": ScenarioMarker,
        "phid_msgs/msg/SetPointBlock": SetPointBlock,
    }


def now_ns(node: Node) -> int:
    return int(node.get_clock().now().nanoseconds)


def subscribe_sensors(node: MonitorNode) -> None:
    """Both nodes' sensor subscriptions: each block goes to ``node.pipeline.ingest_message``, the entry
    point phid replay feeds too, and tells ``node.input`` that data arrived."""
    from phid_ros.stream import messages as m

    values = node.values
    qos = sensor_qos(values["reliable_qos"], values["queue_depth"])
    # a stream's name is its topic, relative to the node's namespace; a recorder's own stream (the
    # field controller's) is optional: kept for the event windows when it comes, never waited for
    streams = (*STREAMS, *RECORDER_STREAMS)
    for spec in streams:

        def callback(msg: Any, stream: str = spec.name, channels: tuple[str, ...] = spec.channels) -> None:
            node.input.on_data()
            node.pipeline.ingest_message(  # a zero stamp is counted and dropped by the pipeline
                stream,
                m.stamp_ns(msg.header.stamp),
                m.seconds_to_ns(msg.sample_period),
                m.block_arrays(msg, channels),
                receive_ns=now_ns(node),
            )

        node.subscription(node.types[spec.msgtype], spec.name, callback, qos)
    node.get_logger().info(
        f"ready: {', '.join(s.name for s in streams)} ({'reliable' if values['reliable_qos'] else 'best effort'}, "
        f"depth {values['queue_depth']})"
    )


def spin_until_shutdown(make_node: Any, args: list[str] | None) -> None:
    """The node skeleton of ros2/demos: init, spin, and a clean exit on Ctrl-C or external shutdown."""
    tune_malloc()  # as the CLI: the recalibration's arrays would fault their pages in at every run
    with one_blas_thread():  # as the CLI: the recalibration's small fits, beside the ingest's threads
        _spin(make_node, args)


def _spin(make_node: Any, args: list[str] | None) -> None:
    rclpy.init(args=args)
    node = make_node()
    stopped = False
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        stopped = True  # asked to stop: leave quietly, the finally block cleans up
    finally:
        # Ctrl-C in a terminal reaches the node twice (the terminal signals the whole process group,
        # and ros2 launch forwards its own): the second must not cut the cleanup short (seen: a
        # KeyboardInterrupt inside destroy_node, "process has died" in the launch log)
        with _sigint_ignored():
            try:
                node.trigger_shutdown()  # the pipeline closed, its store written
            except Exception:  # the context already gone (Ctrl-C): the same cleanup without the state machine
                node.on_shutdown(LifecycleState("shuttingdown", 0))
            node.destroy_node()
            rclpy.try_shutdown()
        if stopped:
            # and after it: rclpy's shutdown puts Python's handler back, and launch's forwarded SIGINT
            # came ~0.2 s after the terminal's, while the interpreter was exiting: it died by the
            # signal ("process has died [exit code -2]") after a clean stop. The process is leaving.
            _set_sigint(signal.SIG_IGN)


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
