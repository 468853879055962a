"""The node shells, exercised through the rclpy test double: wiring, a played bag, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from phid_ros.io.bags.recordings import read_recording
from phid_ros.io.recording import recording_messages
from phid_ros.model.conventions import NS
from phid_ros.stream.levels import Level

BAGS = Path(__file__).resolve().parents[2] / "bags"


def make_nodes(ros, **recal_overrides):
    import rclpy.node

    # the input's end is said by the tests that need it (input._last moved back): on wall time, a
    # loaded machine's pause of 3 s inside a test read as the end and ran the owed recalibration early
    patient = {"end_of_data_s": 3600.0}
    rclpy.node.OVERRIDES["ingest_node"] = {**patient, **rclpy.node.OVERRIDES.get("ingest_node", {})}
    rclpy.node.OVERRIDES["recalibration_node"] = {"store_path": ":memory:", **patient, **recal_overrides}
    from phid_ros.nodes.ingest_node import IngestNode
    from phid_ros.nodes.recalibration_node import RecalibrationNode

    return IngestNode(), RecalibrationNode()


def player(ros):
    """A stand-in for `ros2 bag play`: publishers on the bag's absolute topics."""
    from rclpy.node import Node

    return Node("player")


def play(ros, rec, ingest, recal, *, until_s=None, process_every_s=0.1, mutate=None):
    """Publish the recording's messages in log-time order, firing the nodes' timers on stream time."""
    bag = player(ros)
    pubs = {}
    start = rec.span_ns()[0]
    next_tick = start
    for log_ns, topic, msgtype, msg in recording_messages(rec):
        if until_s is not None and log_ns - start > until_s * NS:
            break
        if mutate:
            msg = mutate(topic, msg)
            if msg is None:
                continue
        if topic not in pubs:
            pubs[topic] = bag.create_publisher(type(msg), topic, None)
        for n in (ingest, recal):
            n.get_clock().ns = log_ns
        pubs[topic].publish(msg)
        while log_ns >= next_tick:
            ingest.process()
            recal.process()
            next_tick += int(process_every_s * NS)
    return bag


def published(node, topic):
    return next(p for p in node.publishers if p.topic == topic).sent


def test_wiring_topics_qos_services_parameters(ros):
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

    from phid_ros.stream.params import INGEST, RECALIBRATION

    ingest, recal = make_nodes(ros)
    subs = {s.topic: s for s in ingest.subscriptions}
    sensors = {"/generator/pt_ct", "/generator/encoder", "/generator/pmu", "/generator/excitation"}
    assert set(subs) == sensors | {"/generator/field_controller", "/generator/set_point"}  # a recorder's own: optional
    assert all(s.qos.reliability == ReliabilityPolicy.BEST_EFFORT for s in subs.values())  # sensor data QoS
    assert {p.topic for p in ingest.publishers} == {"/generator/events", "/generator/event_windows"}
    params = next(p for p in recal.publishers if p.topic == "/generator/parameters")
    assert params.qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert {p.topic for p in recal.publishers} >= {"/generator/hamiltonian", "/diagnostics"}
    assert set(recal.services) == {"/generator/recalibration_node/recalibrate", "/generator/recalibration_node/reset"}
    # an executor takes ready messages in the subscriptions' order: a window's marker before it
    # (a window taken first, behind a long callback, went unnamed on a real launch)
    order = [s.topic for s in recal.subscriptions]
    assert order.index("/phid/scenarios") < order.index("/generator/event_windows")
    for node, table in ((ingest, INGEST), (recal, RECALIBRATION)):
        for t in table:
            d = node.descriptors[t.name]
            # a start-up parameter is set while the node is unconfigured (refused once configured)
            assert d.description == t.description and not d.read_only
            assert bool(d.additional_constraints) == (not t.runtime)
            if t.type is float and t.low is not None:
                assert (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value) == (t.low, t.high)


def test_reliable_qos_is_an_option(ros):
    import rclpy.node
    from rclpy.qos import ReliabilityPolicy

    rclpy.node.OVERRIDES["ingest_node"] = {"reliable_qos": True}
    ingest, _ = make_nodes(ros)
    assert all(s.qos.reliability == ReliabilityPolicy.RELIABLE for s in ingest.subscriptions)


def test_played_bag_gives_the_same_parameters_as_phid_replay(ros):
    from phid_ros.stream.pipeline import MonitorPipeline
    from phid_ros.stream.replay import replay

    rec = read_recording(BAGS / "catalogue")
    ingest, recal = make_nodes(ros)
    play(ros, rec, ingest, recal)
    # end of the bag: the operator asks for a recalibration (the ~/recalibrate service)
    recal.pipeline.recalibrator.join()
    recal.process()
    response = recal.services["/generator/recalibration_node/recalibrate"].call()
    assert response.success and response.message == "started"
    recal.pipeline.recalibrator.join()
    recal.process()
    node_params = published(recal, "/generator/parameters")[-1]
    assert list(node_params.names)[:2] == ["H", "D"]
    reference = MonitorPipeline()
    replay(rec, reference)
    expect = reference.parameters.as_dict()
    got = dict(zip(node_params.names, np.asarray(node_params.values)))
    assert got == expect  # to the last digit
    events = published(ingest, "/generator/events")
    assert len(events) == 18
    # the ingest node hands its windows on and keeps none: its memory does not grow with the events
    assert len(ingest.pipeline.store) == 0 and len(recal.pipeline.store) == 17  # V3: the data end before its end
    energy = published(recal, "/generator/hamiltonian")
    assert len(energy) > 1000 and all(e.passivity_margin >= 0 for e in energy[-100:])
    reference.close()


def test_a_stopped_stream_is_stale_and_its_windows_are_not_used(ros):
    rec = read_recording(BAGS / "validation.mcap")
    ingest, recal = make_nodes(ros)

    def drop_encoder_after_5s(topic, msg):
        t = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
        return None if topic.endswith("/encoder") and t - rec.span_ns()[0] > 5 * NS else msg

    play(ros, rec, ingest, recal, mutate=drop_encoder_after_5s)
    recal.get_clock().ns = rec.span_ns()[1] + 3 * NS
    recal.publish_diagnostics()
    diag = published(recal, "/diagnostics")[-1]
    enc = next(s for s in diag.status if s.name.endswith("encoder stream"))
    assert (
        enc.level == bytes([3]) and "no data" in enc.message
    )  # STALE, as the byte field rclpy takes (an int crashed ROS_PYTHON_CHECK_FIELDS=1)
    assert published(ingest, "/generator/event_windows") == []  # windows with the gap are not sent
    assert any("not usable" in text and "omega" in text for _, text in ingest.get_logger().records)


def test_wrong_rate_and_zero_stamps_are_reported(ros):
    rec = read_recording(BAGS / "validation.mcap")
    ingest, recal = make_nodes(ros)

    def zero_some_pmu(topic, msg):
        if topic.endswith("/pmu") and msg.header.stamp.nanosec // 100_000_000 == 3:
            msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0
        if topic.endswith("/excitation"):
            msg.sample_period = 2e-3  # claims 500 Hz: the stream runs at half the expected rate
        return msg

    play(ros, rec, ingest, recal, until_s=20, mutate=zero_some_pmu)
    h = recal.pipeline.health
    assert h["pmu"].zero_stamps > 0
    level, message = h["excitation"].status()
    assert level in (Level.WARN, Level.ERROR) and "rate 500 Hz" in message


def test_a_stream_slower_than_the_grid_is_judged_at_its_own_rate(ros):
    # a 500 Hz excitation stream beside 1 kHz PT/CT, declared as such: no rate warning, while the
    # same stream undeclared warns (test above)
    rec = read_recording(BAGS / "validation.mcap")
    ingest, recal = make_nodes(ros, excitation_rate_hz=500.0)

    def slow_excitation(topic, msg):
        if topic.endswith("/excitation"):
            msg.sample_period = 2e-3
        return msg

    play(ros, rec, ingest, recal, until_s=20, mutate=slow_excitation)
    h = recal.pipeline.health["excitation"]
    assert h.expected_rate_hz == 500.0 and abs(h.rate_hz() - 500.0) < 5.0
    level, message = h.status()
    assert "rate" not in message, message
    assert recal.pipeline.health["pmu"].expected_rate_hz == 1000.0  # undeclared: the grid's


def test_out_of_range_parameter_is_refused_and_the_old_value_kept(ros):
    from rclpy.node import Parameter

    _, recal = make_nodes(ros)
    before = recal.pipeline.settings.hamiltonian_rate_hz
    result = recal.set_parameters([Parameter("hamiltonian_rate_hz", 5000.0)])[-1]
    assert not result.successful and "outside [0.1, 100.0]" in result.reason
    assert recal.pipeline.settings.hamiltonian_rate_hz == before
    result = recal.set_parameters([Parameter("store_path", "/tmp/x.sqlite")])[-1]
    assert not result.successful and "cannot change while the node is configured" in result.reason
    ok = recal.set_parameters([Parameter("min_interval_s", 60.0)])[-1]
    assert ok.successful and recal.pipeline.recalibrator.policy.min_interval_s == 60.0


def test_a_recalibration_that_throws_keeps_the_node_up(ros, monkeypatch):
    import phid_ros.stream.recalibration as rc
    from phid_ros.model.parameters import TABLE1

    def boom(*a, **k):
        raise RuntimeError("matrix is singular")

    monkeypatch.setattr(rc, "identify", boom)
    rec = read_recording(BAGS / "catalogue")
    ingest, recal = make_nodes(ros)
    recal.pipeline.recalibrator.last_good = TABLE1
    play(ros, rec, ingest, recal, until_s=200)
    recal.pipeline.recalibrator.join()
    recal.process()
    recal.publish_diagnostics()
    status = next(s for s in published(recal, "/diagnostics")[-1].status if s.name.endswith("recalibration"))
    assert status.level == bytes([2]) and "matrix is singular" in status.message  # ERROR
    last = published(recal, "/generator/parameters")[-1]
    assert dict(zip(last.names, np.asarray(last.values))) == TABLE1.as_dict()  # last good kept


def test_main_shuts_down_cleanly(ros):
    import rclpy

    from phid_ros.nodes import ingest_node

    rclpy.node.OVERRIDES["recalibration_node"] = {"store_path": ":memory:"}
    ingest_node.main([])
    assert not rclpy.ok()


def test_config_yaml_holds_the_table_defaults():
    from ruamel.yaml import YAML

    from phid_ros.stream.params import INGEST, RECALIBRATION

    doc = YAML(typ="safe").load((Path(__file__).resolve().parents[2] / "config" / "phid.yaml").read_text())
    for node, table in (("ingest_node", INGEST), ("recalibration_node", RECALIBRATION)):
        values = doc[node]["ros__parameters"]
        assert values == {t.name: t.default for t in table}


def test_launch_file_names_the_installed_executables_and_config_sections():
    import ast
    import re

    root = Path(__file__).resolve().parents[2]
    tree = ast.parse((root / "launch" / "monitor.launch.py").read_text())
    # the nodes: one LifecycleNode a name, made in a comprehension over the executables' names
    made = next(
        n
        for n in ast.walk(tree)
        if isinstance(n, ast.ListComp)
        and isinstance(n.elt, ast.Call)
        and getattr(n.elt.func, "id", "") == "LifecycleNode"
    )
    keywords = {k.arg: ast.unparse(k.value) for k in made.elt.keywords}
    assert keywords["executable"] == keywords["name"] == ast.unparse(made.generators[0].target)
    executables = set(ast.literal_eval(made.generators[0].iter))
    assert executables == {"ingest_node", "recalibration_node"}
    entry_points = set(re.findall(r'"(\w+) = phid_ros\.nodes\.\w+:main"', (root / "setup.py").read_text()))
    assert executables <= entry_points
    comp = next(n for n in ast.walk(tree) if isinstance(n, ast.DictComp) and "node_parameters" in ast.unparse(n))
    sections = set(ast.literal_eval(comp.generators[0].iter))
    assert sections == executables
    # the arguments passed through name real parameters of the nodes they go to
    from phid_ros.stream.params import INGEST, RECALIBRATION

    tables = {"ingest_node": INGEST, "recalibration_node": RECALIBRATION}
    passed = next(n for n in ast.walk(tree) if isinstance(n, ast.Assign) and ast.unparse(n.targets[0]) == "PASSED")
    for key, value in zip(passed.value.keys, passed.value.values):
        kind, nodes = value.elts[0].id, ast.literal_eval(value.elts[1])
        for node in nodes:
            spec = next(t for t in tables[node] if t.name == key.value)
            assert spec.type.__name__ == kind, key.value
    # Jazzy's `--clock` takes an optional rate: the bag must come before it, and the rate is passed
    play = next(n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", "") == "ExecuteProcess")
    cmd = ast.unparse(next(k.value for k in play.keywords if k.arg == "cmd"))
    assert cmd.index("play_bag") < cmd.index("'--clock'") and "'--rate', LaunchConfiguration('play_rate')" in cmd


def test_the_owed_recalibration_is_published_when_the_data_end_without_a_clock(ros):
    """Under sim time the timers stopped with /clock, so the last set never came. Now the process
    timer is on the steady clock and an input that stays silent counts as ended."""
    from phid_ros.stream.pipeline import MonitorPipeline
    from phid_ros.stream.replay import replay

    rec = read_recording(BAGS / "catalogue")
    ingest, recal = make_nodes(ros)
    assert all(t.clock is not None and t.clock.clock_type == 3 for t in recal.timers + ingest.timers)  # steady
    play(ros, rec, ingest, recal)
    before = len(published(recal, "/generator/parameters"))
    recal.input._last -= recal.values["end_of_data_s"] + 1  # the bag ended a while ago (wall time)
    recal.process()  # no clock message, no service call
    params = published(recal, "/generator/parameters")
    assert len(params) > before
    reference = MonitorPipeline()
    replay(rec, reference)
    assert dict(zip(params[-1].names, np.asarray(params[-1].values))) == reference.parameters.as_dict()
    reference.close()
    assert len(published(recal, "/generator/hamiltonian")) > 1000


def test_an_event_in_the_last_seconds_of_the_input_is_published_when_the_input_ends(ros):
    """The ingest node held a window open until data after it came; at the end of a bag none
    comes: the 2 h ambient bag's last event (30 s before its end) was never published. When the
    input has been silent for end_of_data_s, the open windows are cut with what came."""
    from phid_ros.io.recording import Recording, StreamSamples
    from phid_ros.stream.messages import window_from_message as window_from

    whole = read_recording(BAGS / "catalogue")
    t0 = whole.span_ns()[0]
    # the catalogue cut 10 s after its first fault's inception: that window cannot complete
    fault = next(m for m in whole.scenarios if m.kind == "fault")
    end = fault.event_ns + 10 * 10**9
    streams = {}
    for name, s in whole.streams.items():
        keep = s.t_ns <= end
        streams[name] = StreamSamples(s.t_ns[keep], s.period_ns, {c: x[keep] for c, x in s.channels.items()})
    rec = Recording(streams, [m for m in whole.scenarios if m.start_ns < end], whole.metadata)
    assert t0 < end
    ingest, recal = make_nodes(ros)
    play(ros, rec, ingest, recal)
    before = [w.event.inception_ns for w in map(window_from, published(ingest, "/generator/event_windows"))]
    assert fault.event_ns not in before
    ingest.input._last -= ingest.values["end_of_data_s"] + 1  # silent a while (wall time)
    ingest.process()
    after = [window_from(w) for w in published(ingest, "/generator/event_windows")]
    last = after[-1]
    assert abs(last.event.inception_ns - fault.event_ns) < 5 * 10**6 and last.usable
    ingest.process()  # once per stop: nothing more
    assert len(published(ingest, "/generator/event_windows")) == len(after)


def test_the_nodes_are_managed_start_unconfigured_without_autostart_and_follow_their_transitions(ros, tmp_path):
    """Lifecycle as robot_localization and nav2 run it: unconfigured (no topics, no pipeline),
    configure (topics made, nothing sent), activate (data in, outputs out), deactivate (inputs
    ignored, outputs silent, memory kept), cleanup (all taken down; a start-up parameter may change),
    and configure again with the new value."""
    import rclpy.node
    from rclpy.lifecycle import TransitionCallbackReturn as R
    from rclpy.node import Parameter

    rclpy.node.OVERRIDES["ingest_node"] = {"autostart": False}
    ingest, recal = make_nodes(ros, autostart=False)
    for n in (ingest, recal):
        assert n.state == "unconfigured" and n.pipeline is None and not n.publishers and not n.subscriptions
    # a start-up parameter may change now: it takes effect on configure
    assert recal.set_parameters([Parameter("store_path", str(tmp_path / "u1.sqlite"))])[-1].successful
    assert ingest.set_parameters([Parameter("ring_seconds", 60.0)])[-1].successful
    assert ingest.trigger_configure() == R.SUCCESS and recal.trigger_configure() == R.SUCCESS
    assert ingest.pipeline.settings.ring_seconds == 60.0 and recal.pipeline.store.path == str(tmp_path / "u1.sqlite")
    assert {p.topic for p in ingest.publishers} == {"/generator/events", "/generator/event_windows"}
    assert not ingest.timers  # inactive: nothing runs
    assert not ingest.set_parameters([Parameter("ring_seconds", 90.0)])[-1].successful  # configured now
    rec = read_recording(BAGS / "catalogue")
    play(ros, rec, ingest, recal, until_s=60)  # inactive: the data is not taken
    assert ingest.pipeline.health["pt_ct"].samples == 0 and published(ingest, "/generator/events") == []
    assert ingest.trigger_activate() == R.SUCCESS and recal.trigger_activate() == R.SUCCESS
    assert len(ingest.timers) == 1 and len(recal.timers) == 2
    play(ros, rec, ingest, recal, until_s=60)
    events = len(published(ingest, "/generator/events"))
    assert events >= 1 and ingest.pipeline.health["pt_ct"].samples > 0
    assert ingest.trigger_deactivate() == R.SUCCESS
    samples = ingest.pipeline.health["pt_ct"].samples
    play(ros, rec, ingest, recal, until_s=60)
    assert ingest.pipeline.health["pt_ct"].samples == samples and not ingest.timers  # ignored, memory kept
    response = recal.services["/generator/recalibration_node/recalibrate"].call()
    assert response.success  # recal still active
    assert recal.trigger_deactivate() == R.SUCCESS
    response = recal.services["/generator/recalibration_node/recalibrate"].call()
    assert not response.success and "not active" in response.message
    recal.pipeline.recalibrator.join()
    assert ingest.trigger_cleanup() == R.SUCCESS and recal.trigger_cleanup() == R.SUCCESS
    for n in (ingest, recal):
        assert n.state == "unconfigured" and n.pipeline is None
        assert not n.publishers and not n.subscriptions and not n.services and not n.timers
    assert (tmp_path / "u1.sqlite").exists()  # the store closed, not lost
    assert ingest.set_parameters([Parameter("ring_seconds", 90.0)])[-1].successful
    assert ingest.trigger_configure() == R.SUCCESS and ingest.pipeline.settings.ring_seconds == 90.0
    assert ingest.trigger_shutdown() == R.SUCCESS and ingest.state == "finalized" and ingest.pipeline is None


def test_autostart_configures_and_activates_and_a_bad_value_fails_configure_in_one_line(ros):
    import rclpy.node
    from rclpy.lifecycle import TransitionCallbackReturn as R
    from rclpy.node import Parameter

    ingest, recal = make_nodes(ros)
    assert ingest.state == recal.state == "active" and ingest.timers and recal.timers
    rclpy.node.OVERRIDES["recalibration_node"] = {"store_path": "/nonexistent/dir/x.sqlite", "autostart": False}
    from phid_ros.nodes.recalibration_node import RecalibrationNode

    node = RecalibrationNode()
    assert node.trigger_configure() == R.FAILURE and node.state == "unconfigured" and node.pipeline is None
    errors = [text for level, text in node.get_logger().records if level == "error"]
    assert len(errors) == 1 and errors[0].startswith("configure failed:") and "x.sqlite" in errors[0]
    assert not node.subscriptions and not node.publishers  # nothing half-made is left
    assert node.set_parameters([Parameter("store_path", ":memory:")])[-1].successful
    assert node.trigger_configure() == R.SUCCESS


def test_the_record_on_file_gets_the_same_verdicts_on_the_node_as_in_replay(ros, tmp_path):
    """The recalibration node with ``record`` (the unit's .dyr) publishes one ModelValidation an
    event it keeps and the record's state on /diagnostics: replay's verdicts, to the last digit."""
    from phid_ros.api import record_check
    from phid_ros.model.parameters import TABLE1
    from phid_ros.stream.pipeline import MonitorPipeline
    from phid_ros.stream.replay import replay
    from test.stream.test_record_check import record_of

    dyr = record_of(tmp_path, "wrong", TABLE1.replace(X_d_prime=1.2 * TABLE1.X_d_prime))
    rec = read_recording(BAGS / "catalogue")
    ingest, recal = make_nodes(ros, record=str(dyr))
    play(ros, rec, ingest, recal)
    recal.pipeline.recalibrator.join()
    recal.process()
    sent = published(recal, "/generator/model_validation")
    reference = MonitorPipeline()
    reference.record_check = record_check(dyr)
    expect = {v.event_id: v for v in replay(rec, reference).verdicts}
    reference.close()
    assert len(sent) == len(recal.pipeline.store) == 17  # V3's window: the data end before its end
    for msg in sent:
        v = expect[msg.event_id]
        assert list(msg.max_errors) == [c.max_error for c in v.checks] and msg.passed == v.passed
    assert any(not msg.passed for msg in sent) and sent[-1].level in ("WARN", "ERROR")
    recal.publish_diagnostics()
    [diag] = published(recal, "/diagnostics")[-1:]
    [status] = [s for s in diag.status if s.name.endswith("record on file")]
    assert status.level in (b"\x01", b"\x02") and "X'_d: record 0.6" in status.message
