"""Test double of rclpy.node.Node: records the wiring and delivers messages synchronously."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import rclpy

NAMESPACE = ""  # tests set this (a launch file would give --ros-args -r __ns:=...)
OVERRIDES: dict[str, dict[str, Any]] = {}  # node name -> parameter overrides (launch parameters)


@dataclass
class Parameter:
    name: str
    value: Any


@dataclass
class Subscription:
    msg_type: Any
    topic: str
    callback: Callable[[Any], None]
    qos: Any


@dataclass
class Publisher:
    msg_type: Any
    topic: str
    qos: Any
    sent: list[Any] = field(default_factory=list)

    def publish(self, msg: Any) -> None:
        self.sent.append(msg)
        for sub in rclpy.bus.get(self.topic, []):
            sub.callback(msg)


@dataclass
class Service:
    srv_type: Any
    name: str
    callback: Callable[[Any, Any], Any]

    def call(self) -> Any:
        return self.callback(self.srv_type.Request(), self.srv_type.Response())


@dataclass
class Timer:
    period: float
    callback: Callable[[], None]


class Clock:
    def __init__(self) -> None:
        self.ns = 0

    def now(self) -> Any:
        return type("Time", (), {"nanoseconds": self.ns})()


class Logger:
    def __init__(self) -> None:
        self.records: list[tuple[str, str]] = []

    def info(self, msg: str) -> None:
        self.records.append(("info", msg))

    def warning(self, msg: str) -> None:
        self.records.append(("warning", msg))

    def error(self, msg: str) -> None:
        self.records.append(("error", msg))


class Node:
    def __init__(self, node_name: str, **kwargs: Any) -> None:
        self.node_name = node_name
        self.namespace = kwargs.get("namespace", NAMESPACE)
        self.parameters: dict[str, Parameter] = {}
        self.descriptors: dict[str, Any] = {}
        self.subscriptions: list[Subscription] = []
        self.publishers: list[Publisher] = []
        self.services: dict[str, Service] = {}
        self.timers: list[Timer] = []
        self._param_callbacks: list[Callable[[list[Parameter]], Any]] = []
        self._clock = Clock()
        self._logger = Logger()
        rclpy.nodes.append(self)

    def get_namespace(self) -> str:
        return self.namespace

    def resolve(self, name: str) -> str:
        if name.startswith("/"):
            return name
        if name.startswith("~/"):
            return f"{self.namespace}/{self.node_name}/{name[2:]}"
        return f"{self.namespace}/{name}"

    def declare_parameter(self, name: str, value: Any, descriptor: Any = None) -> Parameter:
        value = OVERRIDES.get(self.node_name, {}).get(name, value)
        self.parameters[name] = Parameter(name, value)
        self.descriptors[name] = descriptor
        return self.parameters[name]

    def get_parameter(self, name: str) -> Parameter:
        return self.parameters[name]

    def add_on_set_parameters_callback(self, callback: Callable[[list[Parameter]], Any]) -> None:
        self._param_callbacks.append(callback)

    def set_parameters(self, params: list[Parameter]) -> list[Any]:
        results = []
        for cb in self._param_callbacks:
            r = cb(params)
            results.append(r)
            if not r.successful:
                return results
        for p in params:
            self.parameters[p.name] = p
        return results

    def create_subscription(self, msg_type: Any, topic: str, callback: Callable, qos: Any) -> Subscription:
        sub = Subscription(msg_type, self.resolve(topic), callback, qos)
        self.subscriptions.append(sub)
        rclpy.bus.setdefault(sub.topic, []).append(sub)
        return sub

    def create_publisher(self, msg_type: Any, topic: str, qos: Any) -> Publisher:
        pub = Publisher(msg_type, self.resolve(topic), qos)
        self.publishers.append(pub)
        return pub

    def create_service(self, srv_type: Any, name: str, callback: Callable) -> Service:
        svc = Service(srv_type, self.resolve(name), callback)
        self.services[svc.name] = svc
        return svc

    def create_timer(self, period: float, callback: Callable[[], None], clock: Any = None) -> Timer:
        t = Timer(period, callback)
        t.clock = clock  # type: ignore[attr-defined]
        self.timers.append(t)
        return t

    def get_clock(self) -> Clock:
        return self._clock

    def get_logger(self) -> Logger:
        return self._logger

    def destroy_subscription(self, sub: Subscription) -> None:
        self.subscriptions.remove(sub)
        rclpy.bus.get(sub.topic, []).remove(sub)

    def destroy_publisher(self, pub: Publisher) -> None:
        self.publishers.remove(pub)

    def destroy_service(self, srv: Service) -> None:
        del self.services[srv.name]

    def destroy_timer(self, timer: Timer) -> None:
        self.timers.remove(timer)

    def destroy_node(self) -> None:
        for sub in self.subscriptions:
            rclpy.bus.get(sub.topic, []).remove(sub)
