"""One plant recording, without scenario markers, through the three front-ends.

The two nodes (on the rclpy test double, the ingest node's windows crossing to the
recalibration node as messages), ``phid replay`` and ``phid identify`` must cut the same
windows, sample for sample, and publish the same parameters, to the last digit: one path from
samples to windows to stages, whichever front-end drives it.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from phid_ros.model.channels import channel_columns
from phid_ros.model.conventions import split_stamp
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1
from test.conftest import short
from test.nodes.test_nodes import make_nodes, play, published


@pytest.fixture(scope="module")
def plant(tmp_path_factory):
    """A torque step, two voltage steps and a fault, recorded with no markers.

    The simulator brings the machine back to its operating point after each (a 1 s ramp): those
    are disturbances too. The fault's run goes on for 5 s after its window, as a plant's data go
    on: a node cuts a window once detection has passed its end (up to 3 s later).
    """
    from phid_ros.io.bags.recordings import read_recording, write_recording
    from phid_ros.io.recording import Recording
    from phid_ros.sim.recording import recording_from_runs
    from phid_ros.sim.runner import SimulationConfig, simulate_scenarios

    config = SimulationConfig(restore_ramp=1.0, restore_hold=1.0)
    runs = simulate_scenarios([short("S04", 30.0), short("S08", 30.0), short("S10", 30.0), short("S14", 35.0)], config)
    rec = recording_from_runs(runs, config)
    path = write_recording(tmp_path_factory.mktemp("plant") / "plant.mcap", Recording(rec.streams, [], rec.metadata))
    return path, read_recording(path)


def test_nodes_replay_and_identify_cut_the_same_windows_and_publish_the_same_parameters(ros, plant, tmp_path):
    from phid_ros.cli.main import main
    from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings
    from phid_ros.stream.replay import replay
    from phid_ros.stream.scenarios import scenarios_from_recording

    path, rec = plant
    # the nodes: played as `ros2 bag play` would, then the operator's ~/recalibrate at the end
    ingest, recal = make_nodes(ros)
    play(ros, rec, ingest, recal)
    recal.pipeline.recalibrator.join()
    recal.process()
    assert recal.services["/generator/recalibration_node/recalibrate"].call().success
    recal.pipeline.recalibrator.join()
    recal.process()
    node_windows = recal.pipeline.store.all()
    node_params = published(recal, "/generator/parameters")[-1]
    node = dict(zip(node_params.names, np.asarray(node_params.values).tolist()))

    # phid replay
    pipeline = MonitorPipeline(PipelineSettings())
    replayed = replay(rec, pipeline)
    replay_params = pipeline.parameters.as_dict()
    pipeline.close()

    # phid identify: its scenarios, and its JSON
    scenarios, problems = scenarios_from_recording(rec, str(path))
    out = tmp_path / "r.json"
    assert main(["identify", str(path), "--json", str(out), "--no-baseline"]) == 0
    batch = json.loads(out.read_text())["parameters"]

    # the windows: the four disturbances and the three restorations between them, each 30 s or up
    # to the start of the next one's window
    kinds = [w.event.kind for w in node_windows]
    assert kinds == ["torque_step"] * 2 + ["voltage_step"] * 4 + ["fault"]
    assert all(w.usable for w in node_windows)
    assert [w.event.event_id for w in replayed.windows] == [w.event.event_id for w in node_windows]
    assert [s.name for s in scenarios] == [w.event.event_id for w in node_windows]
    assert any("no scenario markers: 7 disturbance(s)" in p for p in problems)
    for w_node, w_replay, sc in zip(node_windows, replayed.windows, scenarios):
        assert np.array_equal(w_node.t_ns, w_replay.t_ns) and np.array_equal(w_node.values, w_replay.values)
        assert sc.start_ns == int(w_node.t_ns[0]) and sc.kind == w_node.event.kind
        columns = channel_columns(w_node.values)
        for c in ("v_t", "i_d", "i_q", "omega", "p_e", "p_m"):
            assert np.array_equal(sc[c], columns[c]), c

    # the parameters: the same to the last digit, and right
    assert node == replay_params == batch
    for name in PARAMETER_NAMES:
        limit = 0.10 if name == "D" else 0.02
        assert batch[name] == pytest.approx(getattr(TABLE1, name), rel=limit), name


def test_tracking_on_the_node_equals_tracking_in_replay(ros, plant):
    """The tracker runs inside the pipeline: the node's /generator/tracked_parameters are replay's hops."""
    from phid_ros.stream.params import pipeline_settings
    from phid_ros.stream.pipeline import MonitorPipeline
    from phid_ros.stream.replay import replay

    _, rec = plant
    overrides = {"tracking_enabled": True, "tracking_window_s": 30.0, "tracking_hop_s": 30.0, "min_interval_s": 10.0}
    ingest, recal = make_nodes(ros, **overrides)
    play(ros, rec, ingest, recal)
    recal.pipeline.recalibrator.join()
    recal.process()
    node = [
        (m.header.stamp.sec, list(m.names), np.asarray(m.values).tolist())
        for m in published(recal, "/generator/tracked_parameters")
    ]

    pipeline = MonitorPipeline(pipeline_settings(overrides, detect=True))
    out = replay(rec, pipeline)
    pipeline.close()
    hops = out.tracked
    # tracking starts on the first identified set, from the oldest data in the ring (120 s)
    assert len(hops) >= 3 and all(p.t_ns % (30 * 10**9) == 0 for p in hops)
    expect = [(split_stamp(p.t_ns)[0], list(p.estimates), [e.value for e in p.estimates.values()]) for p in hops]
    assert node == expect


def test_the_held_values_and_the_curve_reach_the_recalibration() -> None:
    from phid_ros.stream.params import RECALIBRATION, pipeline_settings, validate

    settings = pipeline_settings({"held": "X_q=0.62, H=2.3", "saturation": "0.1,0.4"}, detect=False)
    assert settings.identify.constraints.fixed == {"X_q": 0.62, "H": 2.3}
    assert settings.identify.constraints.saturation == (0.1, 0.4)
    assert validate(RECALIBRATION, "held", "X_q=abc", running=False) == "held: --fix X_q: 'abc' is not a number"
    assert "needs S(1.2) > S(1.0) > 0" in (validate(RECALIBRATION, "saturation", "0.4,0.1", running=False) or "")
    assert validate(RECALIBRATION, "held", "X_q=0.62", running=True).startswith("held cannot change while")


@pytest.fixture(scope="module")
def trend_log(tmp_path_factory):
    """A commissioning day's trend logs (208 reports/s, jittered, no rotor channels, the field
    current on the controller's stream), imported as a plant engineer does."""
    from phid_ros.io.bags.recordings import read_recording, write_recording
    from phid_ros.io.field.channel_map import load_channel_map
    from phid_ros.io.field.pmu_csv import import_pmu_csv
    from test.io.field.field_sets import trend_log_set

    d = tmp_path_factory.mktemp("trend")
    paths, cmap = trend_log_set(d, TABLE1)
    path = write_recording(d / "day.mcap", import_pmu_csv(paths, load_channel_map(cmap)))
    return read_recording(path)


def test_the_nodes_on_a_trend_log_publish_what_replay_does(ros, trend_log):
    """The field current crosses from the ingest node to the recalibration node inside each
    window message; a window without the rotor's channels is used by both (the recalibration node
    judged it stale before); the last partial set and the exciter are replay's, to the last digit."""
    from phid_ros.io.recording import not_recorded
    from phid_ros.stream.params import pipeline_settings
    from phid_ros.stream.pipeline import MonitorPipeline
    from phid_ros.stream.replay import replay

    absent = ",".join(sorted(not_recorded(trend_log.metadata)))
    rate = 1e9 / trend_log.streams["pt_ct"].period_ns
    import rclpy.node

    rclpy.node.OVERRIDES["ingest_node"] = {"not_recorded": absent, "sample_rate_hz": rate}
    try:
        ingest, recal = make_nodes(ros, not_recorded=absent, held=f"X_q={TABLE1.X_q}")
    finally:
        rclpy.node.OVERRIDES.pop("ingest_node")
    play(ros, trend_log, ingest, recal)
    recal.input._last -= recal.values["end_of_data_s"] + 1  # the bag has ended
    ingest.input._last -= ingest.values["end_of_data_s"] + 1
    ingest.process()
    recal.pipeline.recalibrator.join()
    recal.process()
    recal.pipeline.recalibrator.join()
    recal.process()
    windows = published(ingest, "/generator/event_windows")
    assert len(windows) >= 5 and all(len(w.i_fd) == len(w.v_t) for w in windows)
    assert all(w.usable for w in recal.pipeline.store.all())
    node = published(recal, "/generator/parameters")[-1]
    exciter = [m for m in published(recal, "/generator/control_parameters") if m.kind == "exciter"][-1]

    settings = pipeline_settings(
        {"not_recorded": absent, "sample_rate_hz": rate, "held": f"X_q={TABLE1.X_q}"}, detect=True
    )
    pipeline = MonitorPipeline(settings)
    out = replay(trend_log, pipeline)
    pipeline.close()
    last = out.recalibrations[-1]
    assert [m.event_id for m in windows] == [w.event.event_id for w in out.windows if w.usable]
    assert list(node.names) == list(last.determined) == ["X_d", "X_d_prime", "T_d0_prime"]
    assert np.asarray(node.values).tolist() == [e.value for e in last.determined.values()]
    assert exciter.why == (
        last.controls["exciter"] if isinstance(last.controls["exciter"], str) else last.controls["exciter"].why
    )
