"""rclpy.clock as the nodes use it: a Clock of a given type (the double keeps time by hand)."""

from __future__ import annotations

import enum
from typing import Any


class ClockType(enum.IntEnum):
    UNINITIALIZED = 0
    ROS_TIME = 1
    SYSTEM_TIME = 2
    STEADY_TIME = 3


class Clock:
    def __init__(self, *, clock_type: ClockType = ClockType.SYSTEM_TIME) -> None:
        self.clock_type = clock_type
        self.ns = 0

    def now(self) -> Any:
        return type("Time", (), {"nanoseconds": self.ns})()
