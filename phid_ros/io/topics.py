"""The sensor streams, their channels and topics: one table, used by every layer.

This module imports nothing from phid_ros, so model-side layers (ident, stream)
may use it without depending on the bag and file code in the rest of io/.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


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
CHANNEL_INDEX: dict[str, int] = {c: i for i, c in enumerate(CHANNELS)}  # column of a channel in an aligned frame


def channel_columns(values: Any) -> dict[str, Any]:
    """The columns of an aligned (samples x CHANNELS) matrix by channel name (views, no copies)."""
    return {c: values[:, i] for i, c in enumerate(CHANNELS)}


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
    "tracked_parameters": ("tracked_parameters", "phid_msgs/msg/GeneratorParameters"),
    "hamiltonian": ("hamiltonian", "phid_msgs/msg/HamiltonianState"),
    "diagnostics": ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),  # absolute: the ROS convention
}


def output_topic(key: str, namespace: str = OUTPUT_NAMESPACE) -> str:
    """The absolute name of output ``key`` under ``namespace`` (an absolute topic stays as it is)."""
    name = OUTPUT_TOPICS[key][0]
    return name if name.startswith("/") else f"{namespace.rstrip('/')}/{name}"


# Plausible ranges in per unit / rad on the machine base: anything outside is a wrong feed (a kV, MW
# or A signal by mistake), not a disturbance. One table for replay, identify and import-csv.
PLAUSIBLE: dict[str, tuple[float, float]] = {
    "v_t": (0.0, 3.0),
    "i_d": (-25.0, 25.0),
    "i_q": (-25.0, 25.0),
    "p_e": (-25.0, 25.0),
    "q_e": (-25.0, 25.0),
    "omega": (0.5, 1.5),
    "p_m": (-5.0, 5.0),
    "theta_t": (-1e6, 1e6),
    "delta": (-1e6, 1e6),
    "v_f": (-30.0, 30.0),
}

# What a channel's typical magnitude says it was recorded in, when it is not per unit.
_UNIT_GUESSES: dict[str, tuple[tuple[float, float, str], ...]] = {
    "v_t": ((3.0, 1000.0, "kV: divide by the machine's rated kV"), (1000.0, 1e7, "V: divide by the rated voltage")),
    "i_d": ((25.0, 1e7, "A or kA: divide by the rated current"),),
    "i_q": ((25.0, 1e7, "A or kA: divide by the rated current"),),
    "p_e": ((25.0, 1e7, "MW: divide by the machine's MVA base"),),
    "q_e": ((25.0, 1e7, "Mvar: divide by the machine's MVA base"),),
    "p_m": ((5.0, 1e7, "MW: divide by the machine's MVA base"),),
    "omega": (
        (40.0, 70.0, "Hz: divide by the nominal frequency"),
        (250.0, 400.0, "rad/s: divide by 2π times the nominal frequency"),
        (400.0, 4000.0, "rpm: divide by the synchronous speed"),
    ),
    "v_f": ((30.0, 1e7, "V: divide by the field voltage base"),),
}


def unit_problem(channel: str, values: object, *, share: float = 0.5) -> str | None:
    """Why ``values`` of ``channel`` are not per unit (with a guess at their unit), or None.

    A channel is refused when at least ``share`` of its finite samples lie outside its
    plausible per-unit range; isolated wild samples are the aligner's business (dropped, counted).
    """
    import numpy as np

    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    lo, hi = PLAUSIBLE[channel]
    if x.size == 0:
        return None
    outside = float(np.mean((x < lo) | (x > hi)))
    if outside < share:
        return None
    typical = float(np.median(np.abs(x)))
    guess = next((text for a, b, text in _UNIT_GUESSES.get(channel, ()) if a <= typical < b), None)
    what = f"looks like {guess}" if guess else "not per unit on the machine base"
    return (
        f"channel {channel}: {100 * outside:.0f} % of samples outside the per-unit range {lo:g} to {hi:g} "
        f"(typical magnitude {typical:.4g}): {what}"
    )


def topic_for(stream: str, namespace: str = DEFAULT_NAMESPACE) -> str:
    return f"{namespace.rstrip('/')}/{stream}"
