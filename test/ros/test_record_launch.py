"""launch_testing: the monitor's launch with the unit's record on file (``record:=unit.dyr``),
fed the shipped bag at 20x, publishes on ``model_validation`` the verdicts ``phid replay
--record`` gives, to the last digit, and raises the record's state on /diagnostics (issue 74).

The record is the wrong machine's (X'_d 20 % high, written by ``phid export``). Runs on a ROS 2
Jazzy machine (colcon test); skipped with the reason where rclpy is absent.
"""

import json
import tempfile
import time
import unittest
from pathlib import Path

import pytest

from test.ros.launching import monitor_description, rclpy

BAG = str(Path(__file__).resolve().parents[2] / "bags" / "catalogue")
WORK = Path(tempfile.mkdtemp(prefix="phid_record_launch_"))
STORE = str(WORK / "events.sqlite")
REFERENCE = {}


def wrong_record() -> Path:
    """The catalogue's machine with X'_d 20 % high, as phid export writes a record."""
    from phid_ros.cli.main import main
    from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1

    doc = {
        "parameters": TABLE1.replace(X_d_prime=1.2 * TABLE1.X_d_prime).as_dict(),
        "identifiable": {n: True for n in PARAMETER_NAMES},
        "f_nominal_hz": 50.0,
        "base_mva": 1000.0,
        "operating_point": {"p_m_pu": 0.8},
    }
    (WORK / "wrong.json").write_text(json.dumps(doc))
    out = WORK / "wrong.dyr"
    assert main(["export", str(WORK / "wrong.json"), "--format", "psse-dyr", "--out", str(out)]) == 0
    return out


def replay_verdicts(dyr: Path) -> dict:
    """``phid replay --record`` on the same bag: each event's final verdict."""
    from phid_ros.api import record_check
    from phid_ros.io.bags.recordings import read_recording
    from phid_ros.stream.pipeline import MonitorPipeline
    from phid_ros.stream.replay import replay

    p = MonitorPipeline()
    p.record_check = record_check(dyr)
    out = replay(read_recording(BAG), p)
    p.close()
    return {v.event_id: ([c.max_error for c in v.checks], v.passed) for v in out.verdicts}


@pytest.mark.launch_test
def generate_test_description():
    dyr = wrong_record()
    REFERENCE["verdicts"] = replay_verdicts(dyr)  # before the nodes start, as test_monitor_launch
    return monitor_description(
        {"play_bag": BAG, "play_rate": "20", "store_path": STORE, "end_of_data_s": "10.0", "record": str(dyr)}
    )


class TestTheRecordOnFileOnROS(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rclpy.init()
        cls.node = rclpy.create_node("phid_record_launch_test")

    @classmethod
    def tearDownClass(cls):
        cls.node.destroy_node()
        rclpy.shutdown()

    def test_the_launch_s_verdicts_are_replay_s_and_the_wrong_record_is_raised(self):
        from diagnostic_msgs.msg import DiagnosticArray
        from phid_msgs.msg import ModelValidation
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        expect = REFERENCE["verdicts"]
        got = {"verdicts": {}, "record_status": None}

        def on_verdict(msg):
            got["verdicts"][msg.event_id] = (list(msg.max_errors), msg.passed, msg.level)

        def on_diag(msg):
            for s in msg.status:
                if s.name.endswith("record on file"):
                    got["record_status"] = (bytes(s.level), s.message)

        latched = QoSProfile(
            depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        n = self.node
        n.create_subscription(ModelValidation, "/generator/model_validation", on_verdict, latched)
        n.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)

        def done():
            return len(got["verdicts"]) >= len(expect) - 1  # V3's window: cut by the bag's end, maybe not checked

        deadline = time.time() + 300.0  # playback at 20x and a play-in per event, on a loaded machine
        while time.time() < deadline and not done():
            rclpy.spin_once(n, timeout_sec=0.2)
        drain = time.time() + 5.0
        while time.time() < drain:
            rclpy.spin_once(n, timeout_sec=0.05)

        self.assertGreaterEqual(len(got["verdicts"]), len(expect) - 1, "verdicts published within 300 s")
        for event_id, (errors, passed, _) in got["verdicts"].items():
            self.assertIn(event_id, expect)
            self.assertEqual((errors, passed), expect[event_id], event_id)  # to the last digit
        self.assertTrue(any(not passed for _, passed, _ in got["verdicts"].values()))
        last = max(got["verdicts"].values(), key=lambda v: v[2] != "OK")
        self.assertIn(last[2], ("WARN", "ERROR"))
        self.assertIsNotNone(got["record_status"], "no 'record on file' status on /diagnostics")
        level, message = got["record_status"]
        self.assertIn(level, (b"\x01", b"\x02"), message)
