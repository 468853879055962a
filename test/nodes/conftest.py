"""The nodes run against the rclpy test double (test/rclpy_double), for these tests only."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

DOUBLE = Path(__file__).resolve().parents[1] / "rclpy_double"
DOUBLED = (
    "rclpy",
    "rcl_interfaces",
    "std_srvs",
    "std_msgs",
    "builtin_interfaces",
    "diagnostic_msgs",
    "phid_msgs",
    "_types",
    "phid_ros.nodes",
)


def _purge() -> dict[str, object]:
    """Take the doubled packages out of sys.modules; returns what was there."""
    taken = {}
    for name in list(sys.modules):
        if any(name == d or name.startswith(d + ".") for d in DOUBLED):
            taken[name] = sys.modules.pop(name)
    return taken


@pytest.fixture
def ros(monkeypatch):
    """The double's rclpy module, with a clean bus; the nodes imported against it.

    Under colcon test the real rclpy is importable and may already be loaded (the launch
    test imports it): its modules are put back afterwards, so the double never leaks into a
    test that uses the real one ("No module named 'rclpy.parameter'" otherwise).
    """
    real = _purge()
    monkeypatch.syspath_prepend(str(DOUBLE))
    import rclpy
    import rclpy.node

    rclpy.reset()
    rclpy.node.NAMESPACE = "/generator"
    rclpy.node.OVERRIDES.clear()
    rclpy.init()
    yield rclpy
    _purge()
    sys.modules.update(real)
