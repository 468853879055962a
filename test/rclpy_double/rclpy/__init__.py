"""Test double of rclpy: init/spin/shutdown and the in-process bus."""

from __future__ import annotations

from typing import Any

_initialised = False
bus: dict[str, list[Any]] = {}  # resolved topic -> subscriptions
nodes: list[Any] = []


def init(args: list[str] | None = None) -> None:
    global _initialised
    _initialised = True


def ok() -> bool:
    return _initialised


def spin(node: Any) -> None:  # the double never blocks: tests drive timers themselves
    return None


def try_shutdown() -> None:
    global _initialised
    _initialised = False


def reset() -> None:
    bus.clear()
    nodes.clear()
