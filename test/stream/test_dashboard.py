"""The Foxglove layout shipped for the monitor: made from the topic and parameter tables, naming only
topics the nodes publish or subscribe, and fields their messages have."""

from __future__ import annotations

import json
import re
from pathlib import Path

from phid_ros.io.msg_schemas import typestore
from phid_ros.io.topics import DEFAULT_NAMESPACE, OUTPUT_TOPICS, STREAMS, output_topic, topic_for
from phid_ros.model.parameters import PARAMETER_NAMES, SYMBOLS
from phid_ros.stream.dashboard import foxglove_layout, layout_topics, text

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "config" / "foxglove_monitor.json"
NODE_SOURCES = sorted((ROOT / "phid_ros" / "nodes").glob("*_node.py"))


def _node_outputs() -> set[str]:
    """The output keys the node shells create publishers for, read from their source (the shells
    import rclpy, which the default tests cannot): a layout naming a topic no node publishes fails."""
    keys: set[str] = set()
    for path in NODE_SOURCES:
        source = path.read_text()
        keys |= set(re.findall(r'self\.publisher\("(\w+)"', source))
        for group in re.findall(r"for key in \(([^)]*)\)", source):
            keys |= set(re.findall(r'"(\w+)"', group))
    return keys


def test_the_shipped_layout_is_the_tables_own():
    assert SHIPPED.read_text() == text(), (
        "regenerate: python -m phid_ros.stream.dashboard > config/foxglove_monitor.json"
    )


def test_every_topic_the_layout_names_is_published_or_read_by_the_nodes():
    outputs = _node_outputs()
    assert outputs >= {"events", "windows", "parameters", "hamiltonian", "diagnostics"}, outputs
    published = {output_topic(k, DEFAULT_NAMESPACE) for k in outputs}
    inputs = {topic_for(s.name, DEFAULT_NAMESPACE) for s in STREAMS}
    named = layout_topics(json.loads(SHIPPED.read_text()))
    assert named <= published | inputs, named - published - inputs
    # what the monitor is for: terminal quantities, parameters, the Hamiltonian, the diagnostics
    assert {"/generator/pt_ct", "/generator/parameters", "/generator/hamiltonian", "/diagnostics"} <= named


def test_every_path_is_a_field_of_its_message_and_every_parameter_its_own_index():
    store = typestore()
    msgtype = {output_topic(k, DEFAULT_NAMESPACE): t for k, (_, t) in OUTPUT_TOPICS.items()}
    msgtype |= {topic_for(s.name, DEFAULT_NAMESPACE): s.msgtype for s in STREAMS}
    layout = foxglove_layout()
    paths = [p for c in layout["configById"].values() for p in c.get("paths", [])]
    assert paths
    for p in paths:
        topic, field = p["value"].split(".", 1)
        name = re.match(r"(\w+)", field).group(1)
        fields = [f[0] for f in store.fielddefs[msgtype[topic]][1]]
        assert name in fields, (p["value"], fields)
        index = re.search(r"\[(\d+)\]$", field)
        if topic.endswith("/parameters"):
            # values and std_dev travel in the contract's order: the label must name that index's parameter
            assert SYMBOLS[PARAMETER_NAMES[int(index.group(1))]] in p["label"], p
    plotted = {int(re.search(r"\[(\d+)\]", p["value"]).group(1)) for p in paths if ".values[" in p["value"]}
    assert plotted == set(range(len(PARAMETER_NAMES)))


def test_every_panel_is_placed_once_in_the_arrangement():
    layout = foxglove_layout("/unit2")

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    placed = leaves(layout["layout"])
    assert sorted(placed) == sorted(layout["configById"]) and len(set(placed)) == len(placed)
    assert all(t.startswith("/unit2/") or t == "/diagnostics" for t in layout_topics(layout))
