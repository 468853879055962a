"""Test double of rclpy.lifecycle: the managed-node state machine of ROS 2 (unconfigured,
inactive, active, finalized) with its transitions, and publishers that send only while active."""

from __future__ import annotations

import enum
from typing import Any, NamedTuple

from rclpy.node import Node, Publisher


class TransitionCallbackReturn(enum.Enum):
    SUCCESS = "success"
    FAILURE = "failure"
    ERROR = "error"


class LifecycleState(NamedTuple):
    label: str
    state_id: int


class LifecyclePublisher(Publisher):
    enabled: bool = False

    def publish(self, msg: Any) -> None:
        if self.enabled:  # as rclpy's: an inactive node's message is dropped (rclpy logs it)
            super().publish(msg)


# transition -> (states it may start from, state on success, callback)
TRANSITIONS = {
    "configure": (("unconfigured",), "inactive", "on_configure"),
    "activate": (("inactive",), "active", "on_activate"),
    "deactivate": (("active",), "inactive", "on_deactivate"),
    "cleanup": (("inactive",), "unconfigured", "on_cleanup"),
    "shutdown": (("unconfigured", "inactive", "active"), "finalized", "on_shutdown"),
}


class LifecycleNode(Node):
    def __init__(self, node_name: str, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.state = "unconfigured"
        self.lifecycle_publishers: list[LifecyclePublisher] = []

    def _transition(self, name: str) -> TransitionCallbackReturn:
        sources, target, callback = TRANSITIONS[name]
        if self.state not in sources:
            raise RuntimeError(f"{name} is not a transition from {self.state}")
        try:
            result = getattr(self, callback)(LifecycleState(self.state, 0))
        except Exception:  # rclpy turns an exception into ERROR, and says nothing
            result = TransitionCallbackReturn.ERROR
        if result == TransitionCallbackReturn.SUCCESS:
            self.state = target
        elif result == TransitionCallbackReturn.ERROR:
            self.state = "unconfigured" if self.on_error(LifecycleState(self.state, 0)) else "finalized"
        return result

    def trigger_configure(self) -> TransitionCallbackReturn:
        return self._transition("configure")

    def trigger_activate(self) -> TransitionCallbackReturn:
        return self._transition("activate")

    def trigger_deactivate(self) -> TransitionCallbackReturn:
        return self._transition("deactivate")

    def trigger_cleanup(self) -> TransitionCallbackReturn:
        return self._transition("cleanup")

    def trigger_shutdown(self) -> TransitionCallbackReturn:
        return self._transition("shutdown")

    # the defaults enable and disable the managed publishers, as rclpy's do
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        for p in self.lifecycle_publishers:
            p.enabled = True
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        for p in self.lifecycle_publishers:
            p.enabled = False
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> bool:
        return True

    def create_lifecycle_publisher(self, msg_type: Any, topic: str, qos: Any) -> LifecyclePublisher:
        pub = LifecyclePublisher(msg_type, self.resolve(topic), qos)
        self.publishers.append(pub)
        self.lifecycle_publishers.append(pub)
        return pub

    def destroy_lifecycle_publisher(self, publisher: LifecyclePublisher) -> None:
        self.lifecycle_publishers.remove(publisher)
        self.destroy_publisher(publisher)
