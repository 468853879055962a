"""launch_testing: the launched nodes, fed by a shipped bag, publish parameters and the Hamiltonian.

Runs on a ROS 2 Jazzy machine (colcon test, after building phid_msgs and phid_ros). Where
rclpy is absent it is skipped with that reason: rclpy is neither on PyPI nor in Debian.
"""

import os
import time
import unittest
from pathlib import Path

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
from launch.actions import ExecuteProcess, IncludeLaunchDescription  # noqa: E402
from launch.launch_description_sources import PythonLaunchDescriptionSource  # noqa: E402

BAG = str(Path(__file__).resolve().parents[2] / "bags" / "catalogue")


@pytest.mark.launch_test
def generate_test_description():
    share = get_package_share_directory("phid_ros")
    monitor = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(os.path.join(share, "launch", "monitor.launch.py")),
        launch_arguments={"use_sim_time": "true"}.items(),
    )
    play = ExecuteProcess(cmd=["ros2", "bag", "play", "--clock", "--rate", "20", BAG], output="screen")
    return launch.LaunchDescription([monitor, play, launch_testing.actions.ReadyToTest()])


class TestParametersAndHamiltonianArrive(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rclpy.init()
        cls.node = rclpy.create_node("phid_launch_test")

    @classmethod
    def tearDownClass(cls):
        cls.node.destroy_node()
        rclpy.shutdown()

    def test_parameters_and_hamiltonian(self):
        from phid_msgs.msg import GeneratorParameters, HamiltonianState
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        got = {"parameters": [], "hamiltonian": []}
        latched = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        self.node.create_subscription(GeneratorParameters, "/generator/parameters", got["parameters"].append, latched)
        self.node.create_subscription(HamiltonianState, "/generator/hamiltonian", got["hamiltonian"].append, 10)
        deadline = time.time() + 120.0
        while time.time() < deadline and not (got["parameters"] and len(got["hamiltonian"]) > 10):
            rclpy.spin_once(self.node, timeout_sec=0.5)
        self.assertTrue(got["parameters"], "no parameters published within 120 s")
        self.assertGreater(len(got["hamiltonian"]), 10)
        p = dict(zip(got["parameters"][-1].names, got["parameters"][-1].values))
        self.assertAlmostEqual(p["H"], 3.48, delta=0.1)
