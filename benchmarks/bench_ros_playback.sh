#!/usr/bin/env bash
# Samples received vs sent at several playback rates, on a real ROS 2 Jazzy (needs
# /opt/ros2_jazzy/setup.sh and a colcon workspace with both packages built).
#
#   bash benchmarks/bench_ros_playback.sh WORKSPACE [RATE ...]      # default rates: 1 20 50
#
# For each rate: launches the README's monitor with play_bag:=bags/catalogue, watches the
# outputs (benchmarks/ros_watch.py) until every sample is in and the parameters settle, and prints per stream
# the samples the recalibration node received of the 660 000 sent, the samples missing in gaps,
# the events and windows, the number of Hamiltonian messages, the diagnostics levels seen, and
# whether the final parameters equal `phid replay`'s to the last digit, and the playback's
# effective rate (a reliable subscription slows the player to what the nodes take).
# Extra launch arguments: EXTRA="reliable_qos:=false" bash benchmarks/bench_ros_playback.sh ...
set -euo pipefail
WS=${1:?usage: bench_ros_playback.sh WORKSPACE [RATE ...]}
shift
RATES=${*:-1 20 50}
HERE=$(cd "$(dirname "$0")" && pwd)
BAG=$(cd "$HERE/../bags/catalogue" && pwd)
set +u
source /opt/ros2_jazzy/setup.sh
source "$WS/install/setup.bash"
set -u
export ROS_PYTHON_CHECK_FIELDS=1
OUT=$(mktemp -d)
python3 - "$BAG" "$OUT/replay.json" <<'PY'
import json, sys
from phid_ros.stream.replay import replay
from phid_ros.io.bags.recordings import read_recording
from phid_ros.stream.pipeline import MonitorPipeline
p = MonitorPipeline(); out = replay(read_recording(sys.argv[1]), p)
json.dump({"parameters": p.parameters.as_dict(), "hamiltonian": sum(len(e.t_ns) for e in out.energy)}, open(sys.argv[2], "w"))
p.close()
PY
set -m  # each launch in its own process group, so Ctrl-C (SIGINT) reaches it and its nodes
for rate in $RATES; do
  limit=$(python3 -c "print(int(660 / $rate * 3 + 120))")
  ros2 launch phid_ros monitor.launch.py play_bag:="$BAG" play_rate:="$rate" store_path:="$OUT/ev$rate.sqlite" ${EXTRA:-} \
    > "$OUT/launch$rate.log" 2>&1 &
  launch=$!
  python3 "$HERE/ros_watch.py" "$limit" > "$OUT/watch$rate.json"
  kill -INT -- -$launch; wait $launch || true
  python3 - "$rate" "$OUT/watch$rate.json" "$OUT/replay.json" <<'PY'
import json, sys
rate, w, r = sys.argv[1], json.load(open(sys.argv[2])), json.load(open(sys.argv[3]))
d = w["diag"] or {}
streams = {k.split(": ")[1].split()[0]: v for k, v in d.items() if k.endswith("stream")}
recv = ", ".join(f"{s} {v['samples']} (missing {v['missing']})" for s, v in streams.items())
same = w["parameters"] == r["parameters"]
print(f"{rate}x: received of 660000 per stream: {recv}; events {w['events']}, windows {w['windows']}, "
      f"Hamiltonian {w['hamiltonian']} (replay {r['hamiltonian']}), levels {w['levels']}, "
      f"parameters equal to phid replay: {same}, playback {w['playback_s']} s "
      f"({660 / w['playback_s'] if w['playback_s'] else float('nan'):.1f}x real time), wall {w['wall_s']} s")
PY
done
