"""The sensor streams, their channels and topics: one table, used by every layer.

This module imports nothing from phid_ros, so model-side layers (ident, stream)
may use it without depending on the bag and file code in the rest of io/.
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
CHANNELS: tuple[str, ...] = ("v_t", "theta_t", "i_d", "i_q", "omega", "delta", "v_f", "p_m", "p_e", "q_e")
STREAM_OF_CHANNEL: dict[str, str] = {c: s.name for s in STREAMS for c in s.channels}

DEFAULT_NAMESPACE = "/generator"
SCENARIO_TOPIC = "/phid/scenarios"
SCENARIO_MSGTYPE = "phid_msgs/msg/ScenarioMarker"


def topic_for(stream: str, namespace: str = DEFAULT_NAMESPACE) -> str:
    return f"{namespace.rstrip('/')}/{stream}"
