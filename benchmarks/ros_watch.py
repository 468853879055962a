"""Watch the monitor's outputs until every sample is in and the parameters settle; print a summary as JSON.

Used by bench_ros_playback.sh on a ROS 2 Jazzy machine: python3 ros_watch.py [LIMIT_S]
"""

import json
import sys
import time
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from phid_msgs.msg import DisturbanceEvent, EventWindow, GeneratorParameters, HamiltonianState
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

limit = float(sys.argv[1]) if len(sys.argv) > 1 else 300
rclpy.init()
node = rclpy.create_node("phid_watch")
got: dict[str, Any] = {"parameters": [], "hamiltonian": 0, "events": 0, "windows": [], "diag": None, "levels": set()}
latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
node.create_subscription(
    GeneratorParameters,
    "/generator/parameters",
    lambda m: got["parameters"].append(dict(zip(m.names, m.values))),
    latched,
)
node.create_subscription(
    HamiltonianState, "/generator/hamiltonian", lambda m: got.__setitem__("hamiltonian", got["hamiltonian"] + 1), 5000
)
node.create_subscription(
    DisturbanceEvent, "/generator/events", lambda m: got.__setitem__("events", got["events"] + 1), 50
)
node.create_subscription(EventWindow, "/generator/event_windows", lambda m: got["windows"].append(m.event_id), 50)


def diag(m):
    for s in m.status:
        got["levels"].add(s.level)
    got["diag"] = {
        s.name: {kv.key: kv.value for kv in s.values} | {"level": s.level[0], "message": s.message} for s in m.status
    }


node.create_subscription(DiagnosticArray, "/diagnostics", diag, 10)
SENT = 660_000  # samples per stream in the catalogue bag
t0 = time.time()
last_change = t0
first_data = complete_at = None
n = 0
while time.time() - t0 < limit:
    rclpy.spin_once(node, timeout_sec=0.2)
    if len(got["parameters"]) != n:
        n = len(got["parameters"])
        last_change = time.time()
    counts = [int(v["samples"]) for k, v in (got["diag"] or {}).items() if k.endswith("stream")]
    if first_data is None and any(counts):
        first_data = time.time()
    if complete_at is None and len(counts) == 4 and min(counts) >= SENT:
        complete_at = time.time()
    # a reliable subscription slows the player to what the nodes take, so the end is when
    # every sample has arrived and the final set (end_of_data_s later) has settled
    if complete_at is not None and n and time.time() - max(last_change, complete_at) > 15:
        break
out = {
    "wall_s": round(time.time() - t0, 1),
    "playback_s": round(complete_at - first_data, 1) if complete_at and first_data else None,
    "parameters": got["parameters"][-1] if got["parameters"] else None,
    "n_parameter_sets": n,
    "hamiltonian": got["hamiltonian"],
    "events": got["events"],
    "windows": len(got["windows"]),
    "levels": sorted(level[0] for level in got["levels"]),
    "diag": got["diag"],
}
print(json.dumps(out))
node.destroy_node()
rclpy.shutdown()
