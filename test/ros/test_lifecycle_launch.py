"""launch_testing: the monitor's nodes are managed nodes. Launched with autostart:=false they wait
unconfigured; the lifecycle services (what `ros2 lifecycle set` calls) take them through configure,
activate, deactivate and cleanup, and their topics come and go with the transitions.

Runs on a ROS 2 Jazzy machine (colcon test); skipped where rclpy is absent, saying so.
"""

import os
import time
import unittest

import pytest

from test.ros.launching import monitor_description, rclpy

STORE = f"/tmp/phid_lifecycle_test_{os.getpid()}.sqlite"
NODES = ("/generator/ingest_node", "/generator/recalibration_node")


@pytest.mark.launch_test
def generate_test_description():
    return monitor_description({"autostart": "false", "store_path": STORE}, check_fields=False)


class TestTheNodesFollowTheirLifecycle(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rclpy.init()
        cls.node = rclpy.create_node("phid_lifecycle_test")

    @classmethod
    def tearDownClass(cls):
        cls.node.destroy_node()
        rclpy.shutdown()

    def call(self, client, request, timeout=60.0):
        self.assertTrue(client.wait_for_service(timeout_sec=timeout), f"{client.srv_name} not offered")
        future = client.call_async(request)
        deadline = time.time() + timeout
        while time.time() < deadline and not future.done():
            rclpy.spin_once(self.node, timeout_sec=0.1)
        self.assertTrue(future.done(), f"{client.srv_name}: no answer within {timeout} s")
        return future.result()

    def state(self, name):
        from lifecycle_msgs.srv import GetState

        return self.call(self.node.create_client(GetState, f"{name}/get_state"), GetState.Request()).current_state.label

    def change(self, name, label):
        from lifecycle_msgs.msg import Transition
        from lifecycle_msgs.srv import ChangeState

        request = ChangeState.Request(transition=Transition(label=label))
        return self.call(self.node.create_client(ChangeState, f"{name}/change_state"), request).success

    def publishers(self, topic, expect, timeout=20.0):
        """The number of publishers on ``topic`` once it reaches ``expect`` (discovery takes a moment)."""
        deadline = time.time() + timeout
        while time.time() < deadline and self.node.count_publishers(topic) != expect:
            rclpy.spin_once(self.node, timeout_sec=0.2)
        return self.node.count_publishers(topic)

    def test_unconfigured_then_configure_activate_deactivate_cleanup(self):
        for name in NODES:
            self.assertEqual(self.state(name), "unconfigured", name)
        self.assertEqual(self.publishers("/generator/parameters", 0), 0)
        self.assertEqual(self.publishers("/generator/events", 0), 0)
        for label, state in (("configure", "inactive"), ("activate", "active")):
            for name in NODES:
                self.assertTrue(self.change(name, label), f"{name}: {label}")
                self.assertEqual(self.state(name), state, name)
        self.assertEqual(self.publishers("/generator/parameters", 1), 1)
        self.assertEqual(self.publishers("/generator/events", 1), 1)
        from std_srvs.srv import Trigger

        recalibrate = self.node.create_client(Trigger, "/generator/recalibration_node/recalibrate")
        answer = self.call(recalibrate, Trigger.Request())
        self.assertFalse(answer.success)  # active, and an empty store: the node says why
        self.assertNotIn("not active", answer.message)
        for label, state in (("deactivate", "inactive"), ("cleanup", "unconfigured")):
            for name in NODES:
                self.assertTrue(self.change(name, label), f"{name}: {label}")
                self.assertEqual(self.state(name), state, name)
        self.assertEqual(self.publishers("/generator/parameters", 0), 0)
        self.assertEqual(self.publishers("/generator/events", 0), 0)
        # and up again, as a lifecycle manager restarts a node
        self.assertTrue(self.change(NODES[0], "configure"))
        self.assertEqual(self.publishers("/generator/events", 1), 1)
