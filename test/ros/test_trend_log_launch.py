"""launch_testing: a plant's recorder through the README's launch at 20x gives what `phid replay` gives.

A commissioning day's trend logs, simulated (the TABLE 1 machine; 208 reports/s with jitter;
V_t, P, Q, I_t, E_fd and the field current on the controller's own stream, no rotor channels),
imported as a plant engineer imports them, played by the monitor's launch with the recorder's
options (`sample_rate_hz`, `not_recorded`, `held`): the field current crosses to the
recalibration node inside each window, the partial set and the exciter are replay's, and every
declared stream is healthy. Runs under colcon test on a ROS 2 Jazzy machine; skipped elsewhere.
"""

import tempfile
import time
import unittest
from pathlib import Path

import pytest

from test.ros.launching import monitor_description, rclpy

FOLDER = Path(tempfile.mkdtemp(prefix="phid_trend_launch_"))
STORE = str(FOLDER / "events.sqlite")
REFERENCE = {}


@pytest.mark.launch_test
def generate_test_description():
    bag, options = trend_log_bag()
    REFERENCE.update(replay_reference(bag, options))
    return monitor_description(
        {"play_bag": str(bag), "play_rate": "20", "store_path": STORE, "end_of_data_s": "10.0", **options}
    )


def trend_log_bag():
    """The simulated day imported to one .mcap, and the launch options a plant engineer gives it."""
    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.io.field.channel_map import load_channel_map
    from phid_ros.io.field.pmu_csv import import_pmu_csv
    from phid_ros.io.recording import not_recorded
    from phid_ros.model.parameters import TABLE1
    from test.io.field.field_sets import trend_log_set

    paths, cmap = trend_log_set(FOLDER, TABLE1)
    rec = import_pmu_csv(paths, load_channel_map(cmap))
    bag = write_recording(FOLDER / "day.mcap", rec)
    options = {
        "sample_rate_hz": repr(1e9 / rec.streams["pt_ct"].period_ns),  # the recorder's own grid
        "not_recorded": ",".join(sorted(not_recorded(rec.metadata))),
        "held": f"X_q={TABLE1.X_q}",
    }
    return bag, options


def replay_reference(bag, options):
    """What `phid replay` publishes for the bag with the same options."""
    from phid_ros.io.bags.recordings import read_recording
    from phid_ros.stream.params import pipeline_settings
    from phid_ros.stream.pipeline import MonitorPipeline
    from phid_ros.stream.replay import replay

    p = MonitorPipeline(pipeline_settings({**options, "sample_rate_hz": float(options["sample_rate_hz"])}, detect=True))
    out = replay(read_recording(bag), p)
    p.close()
    last = out.recalibrations[-1]
    exciter = last.controls.get("exciter")
    return {
        "determined": {n: e.value for n, e in last.determined.items()},
        "usable_ids": sorted(w.event.event_id for w in out.windows if w.usable),
        "exciter_why": (exciter if isinstance(exciter, str) else exciter.why).split(":")[0],
    }


class TestTheMonitorOnARecorderEqualsReplay(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rclpy.init()
        cls.node = rclpy.create_node("phid_trend_launch_test")

    @classmethod
    def tearDownClass(cls):
        cls.node.destroy_node()
        rclpy.shutdown()

    def test_partial_set_exciter_windows_and_health(self):
        from diagnostic_msgs.msg import DiagnosticArray
        from phid_msgs.msg import ControlParameters, EventWindow, GeneratorParameters
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        expect = REFERENCE["determined"]
        got = {"parameters": [], "controls": [], "windows": [], "with_i_fd": 0, "diag": {}}

        def on_window(m):
            got["windows"].append(m.event_id)
            got["with_i_fd"] += len(m.i_fd) == len(m.v_t) > 0

        def on_diag(msg):
            for s in msg.status:
                got["diag"].setdefault(s.name, []).append((bytes(s.level), s.message))

        def latched(depth):
            return QoSProfile(
                depth=depth, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
            )

        n = self.node
        n.create_subscription(GeneratorParameters, "/generator/parameters", got["parameters"].append, latched(1))
        n.create_subscription(ControlParameters, "/generator/control_parameters", got["controls"].append, latched(3))
        n.create_subscription(EventWindow, "/generator/event_windows", on_window, 50)
        n.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)

        def final():
            p = got["parameters"]
            return bool(p) and list(p[-1].names) == list(expect) and sorted(got["windows"]) == REFERENCE["usable_ids"]

        deadline = time.time() + 240.0  # the nodes' start, 10 s of playback, the final run, on a loaded machine
        while time.time() < deadline and not final():
            rclpy.spin_once(n, timeout_sec=0.2)
        drain = time.time() + 5.0  # the control systems published with the final set, the last diagnostics
        while time.time() < drain:
            rclpy.spin_once(n, timeout_sec=0.05)

        self.assertTrue(got["parameters"], "no parameters published within 240 s")
        last = got["parameters"][-1]
        self.assertEqual(list(last.names), list(expect), last.status)
        for name, value in zip(last.names, last.values):  # the ROS venv's numpy: equal to 1e-9, not bit for bit
            self.assertAlmostEqual(value / expect[name], 1.0, delta=1e-9, msg=name)
        self.assertEqual(sorted(got["windows"]), REFERENCE["usable_ids"])
        self.assertEqual(got["with_i_fd"], len(got["windows"]), "every window carries the field current")
        exciter = [m for m in got["controls"] if m.kind == "exciter"]
        self.assertTrue(exciter, "no exciter published beside the parameters")
        self.assertEqual(exciter[-1].why.split(":")[0], REFERENCE["exciter_why"])
        streams = {k: v for k, v in got["diag"].items() if k.endswith("stream")}
        self.assertEqual(len(streams), 5, streams)  # the four sensor streams and the field controller's
        # healthy while the bag plays: OK, or stale only for want of any data on the receiver's clock
        # (before the first block, and after the last: the player's /clock runs on at 20x while it
        # waits for the acknowledgements, and a stream is then rightly stale); never a warning
        for name, seen in streams.items():
            self.assertIn(b"\x00", [level for level, _ in seen], name)
            odd = [
                (level, m) for level, m in seen if level != b"\x00" and not m.startswith(("no data yet", "no data for"))
            ]
            self.assertFalse(odd, name)
