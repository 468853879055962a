"""What every launch test needs: ROS 2 itself (a module importing this is skipped, saying why,
where rclpy is absent: it is neither on PyPI nor in Debian) and the monitor's launch file."""

import os
from typing import Any

import pytest

rclpy = pytest.importorskip(
    "rclpy",
    reason="rclpy is not installable here (not on PyPI, not in Debian); "
    "this launch test runs under colcon test on a ROS 2 Jazzy machine",
)
pytest.importorskip("launch_testing", reason="launch_testing comes with ROS 2")

import launch  # noqa: E402
import launch_testing.actions  # noqa: E402
from ament_index_python.packages import get_package_share_directory  # noqa: E402
from launch.actions import IncludeLaunchDescription, SetEnvironmentVariable  # noqa: E402
from launch.launch_description_sources import PythonLaunchDescriptionSource  # noqa: E402


def monitor_description(arguments: dict[str, str], *, check_fields: bool = True) -> Any:
    """The installed ``monitor.launch.py`` with ``arguments``, ready to test. ``check_fields``: the
    nodes run with ROS_PYTHON_CHECK_FIELDS=1, so a message field of the wrong type crashes them."""
    share = get_package_share_directory("phid_ros")
    monitor = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(os.path.join(share, "launch", "monitor.launch.py")),
        launch_arguments=arguments.items(),
    )
    env = [SetEnvironmentVariable("ROS_PYTHON_CHECK_FIELDS", "1")] if check_fields else []
    return launch.LaunchDescription([*env, monitor, launch_testing.actions.ReadyToTest()])


def share_directory() -> str:
    return get_package_share_directory("phid_ros")
