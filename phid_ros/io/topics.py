"""The sensor streams (which channels each message carries), and the topics: one table.

The channels themselves, their column in a frame and their plausible ranges are the model's
(:mod:`phid_ros.model.channels`); this module says how they travel. It imports nothing else
from phid_ros, so the stream layer may use it without the bag and file code in the rest of io/.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class StreamSpec:
    name: str  # stream key, also the relative topic name used by the nodes
    msgtype: str
    channels: tuple[str, ...]
    description: str


STREAMS: tuple[StreamSpec, ...] = (
    StreamSpec(
        "pt_ct",
        "phid_msgs/msg/PtCtBlock",
        ("v_t", "i_d", "i_q", "p_e", "q_e"),
        "potential/current transformers with Park transform",
    ),
    StreamSpec("encoder", "phid_msgs/msg/EncoderBlock", ("omega", "p_m"), "shaft speed encoder and mechanical power"),
    StreamSpec("pmu", "phid_msgs/msg/PmuBlock", ("theta_t", "delta"), "phasor measurement unit angles"),
    StreamSpec("excitation", "phid_msgs/msg/ExcitationBlock", ("v_f",), "excitation system field voltage"),
)
STREAMS_BY_NAME: dict[str, StreamSpec] = {s.name: s for s in STREAMS}
STREAM_OF_CHANNEL: dict[str, str] = {c: s.name for s in STREAMS for c in s.channels}

# What a recorder keeps beside the sensor streams: an excitation controller's field current,
# regulator output and stabiliser output, and the regulator's set-point. Not a frame's channels
# (the online pipeline neither needs nor waits for them): an import writes them, identify reads
# them on each scenario's stamps (the field base, a limit's flat top, the stabiliser's output,
# the exciter's input as it was moved).
RECORDER_STREAMS: tuple[StreamSpec, ...] = (
    StreamSpec(
        "field_controller",
        "phid_msgs/msg/FieldControllerBlock",
        ("i_fd", "v_r", "v_s"),
        "excitation controller's field current, regulator output and stabiliser output",
    ),
    StreamSpec("set_point", "phid_msgs/msg/SetPointBlock", ("v_ref",), "voltage regulator's set-point"),
)
RECORDER_CHANNELS: tuple[str, ...] = tuple(c for s in RECORDER_STREAMS for c in s.channels)
# every stream a recording may carry, by name
ALL_STREAMS_BY_NAME: dict[str, StreamSpec] = {s.name: s for s in (*STREAMS, *RECORDER_STREAMS)}


DEFAULT_NAMESPACE = "/generator"
SCENARIO_TOPIC = "/phid/scenarios"
SCENARIO_MSGTYPE = "phid_msgs/msg/ScenarioMarker"

# What the nodes publish: key -> (topic relative to the node's namespace, type). The nodes run in the
# launch file's namespace (DEFAULT_NAMESPACE); phid replay and phid track write the same topics under
# OUTPUT_NAMESPACE in their output bags, next to the /phid/scenarios markers.
OUTPUT_NAMESPACE = "/phid"
OUTPUT_TOPICS: dict[str, tuple[str, str]] = {
    "events": ("events", "phid_msgs/msg/DisturbanceEvent"),
    "windows": ("event_windows", "phid_msgs/msg/EventWindow"),
    "parameters": ("parameters", "phid_msgs/msg/GeneratorParameters"),
    "controls": ("control_parameters", "phid_msgs/msg/ControlParameters"),  # exciter, governor, stabiliser
    "tracked_parameters": ("tracked_parameters", "phid_msgs/msg/GeneratorParameters"),
    "model_validation": ("model_validation", "phid_msgs/msg/ModelValidation"),  # the record on file, per event
    "hamiltonian": ("hamiltonian", "phid_msgs/msg/HamiltonianState"),
    "diagnostics": ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),  # absolute: the ROS convention
}


def output_topic(key: str, namespace: str = OUTPUT_NAMESPACE) -> str:
    """The absolute name of output ``key`` under ``namespace`` (an absolute topic stays as it is)."""
    name = OUTPUT_TOPICS[key][0]
    return name if name.startswith("/") else f"{namespace.rstrip('/')}/{name}"


def topic_for(stream: str, namespace: str = DEFAULT_NAMESPACE) -> str:
    return f"{namespace.rstrip('/')}/{stream}"
