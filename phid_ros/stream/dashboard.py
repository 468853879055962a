"""The monitor's Foxglove layout, made from the topic and parameter tables (one place for both).

The shipped file ``config/foxglove_monitor.json`` is this module's output for the default
namespace; ``python -m phid_ros.stream.dashboard [NAMESPACE] > FILE`` writes one for another
unit. Import it in Foxglove (Layouts, Import from file) with a ROS 2 connection to the running nodes
(foxglove_bridge) or a bag recorded from them (``ros2 bag record``). The panels: the terminal quantities, the identified
parameters and their one-σ uncertainties, the Port-Hamiltonian energy and its stores, the stream and
recalibration diagnostics, the last parameter set, the control systems fitted beside it and the
disturbance events as messages.

Foxglove's layout format: panels by id in ``configById`` (``Type!suffix``), their arrangement in
``layout`` (a binary tree of row and column splits); a Plot panel's ``paths`` are message paths,
``/topic.field[index]``.
"""

from __future__ import annotations

import json
import sys
from typing import Any

from phid_ros.io.topics import DEFAULT_NAMESPACE, output_topic, topic_for
from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME, SYMBOLS

# the terminal quantities a plant's transducers give (first sample of each block: a block at
# 1 kHz arrives every 0.1 s, plenty for a screen)
TERMINAL = (("pt_ct", "v_t", "V_t (pu)"), ("pt_ct", "p_e", "P (pu)"), ("pt_ct", "q_e", "Q (pu)"))
FIELD = (("excitation", "v_f", "E_fd (pu)"), ("encoder", "omega", "ω (pu)"))
HAMILTONIAN_FIELDS: tuple[tuple[str, str], ...] = (
    ("value", "H(x) (pu·s)"),
    ("kinetic", "kinetic"),
    ("magnetic_d", "magnetic d"),
    ("magnetic_q", "magnetic q"),
)
# parameters plotted on shared axes: similar magnitudes and units
PARAMETER_GROUPS = (("H", "T_d0_prime"), ("X_d", "X_q", "X_d_prime", "X_q_prime"), ("D", "T_q0_prime"))


def _series(path: str, label: str, color: str | None = None) -> dict[str, Any]:
    out: dict[str, Any] = {"value": path, "enabled": True, "timestampMethod": "headerStamp", "label": label}
    if color is not None:
        out["color"] = color
    return out


def _plot(title: str, series: list[dict[str, Any]]) -> dict[str, Any]:
    return {
        "title": title,
        "paths": series,
        "showXAxisLabels": True,
        "showYAxisLabels": True,
        "showLegend": True,
        "legendDisplay": "top",
        "isSynced": True,
        "xAxisVal": "timestamp",
    }


def parameter_series(namespace: str, names: tuple[str, ...], field: str = "values") -> list[dict[str, Any]]:
    """Each parameter's value (or its one-σ ``std_dev``). The message carries the parameters by index
    in the contract's order, so the index is taken from that order, never written by hand."""
    topic = output_topic("parameters", namespace)
    out = []
    for n in names:
        unit = SPECS_BY_NAME[n].unit
        label = f"{SYMBOLS[n]} ({unit})" if unit else SYMBOLS[n]
        out.append(
            _series(f"{topic}.{field}[{PARAMETER_NAMES.index(n)}]", label if field == "values" else f"σ {label}")
        )
    return out


def foxglove_layout(namespace: str = DEFAULT_NAMESPACE) -> dict[str, Any]:
    panels: dict[str, dict[str, Any]] = {}
    panels["Plot!terminal"] = _plot(
        "Terminal quantities", [_series(f"{topic_for(s, namespace)}.{c}[0]", label) for s, c, label in TERMINAL]
    )
    panels["Plot!field"] = _plot(
        "Field voltage and speed", [_series(f"{topic_for(s, namespace)}.{c}[0]", label) for s, c, label in FIELD]
    )
    for i, group in enumerate(PARAMETER_GROUPS):
        title = "Identified parameters: " + ", ".join(SYMBOLS[n] for n in group)
        panels[f"Plot!parameters{i}"] = _plot(title, parameter_series(namespace, group))
    # a plot has no error bars: the one-σ uncertainties are their own panel, on their own scale
    panels["Plot!uncertainty"] = _plot(
        "One standard deviation of each parameter", parameter_series(namespace, PARAMETER_NAMES, "std_dev")
    )
    energy = output_topic("hamiltonian", namespace)
    panels["Plot!hamiltonian"] = _plot(
        "Port-Hamiltonian energy and its stores", [_series(f"{energy}.{f}", label) for f, label in HAMILTONIAN_FIELDS]
    )
    panels["DiagnosticSummary!health"] = {
        "topicToRender": output_topic("diagnostics", namespace),
        "minLevel": 0,
        "pinnedIds": [],
        "hardwareIdFilter": "",
        "sortByLevel": True,
    }
    panels["RawMessages!parameters"] = {"topicPath": output_topic("parameters", namespace), "diffEnabled": False}
    panels["RawMessages!events"] = {"topicPath": output_topic("events", namespace), "diffEnabled": False}
    # the exciter and the stabiliser fitted beside the machine: their models and constants as published
    panels["RawMessages!controls"] = {"topicPath": output_topic("controls", namespace), "diffEnabled": False}
    layout = {
        "direction": "row",
        "splitPercentage": 55,
        "first": {
            "direction": "column",
            "first": {"direction": "column", "first": "Plot!terminal", "second": "Plot!field"},
            "second": {"direction": "column", "first": "Plot!hamiltonian", "second": "DiagnosticSummary!health"},
        },
        "second": {
            "direction": "column",
            "splitPercentage": 70,
            "first": {
                "direction": "column",
                "first": "Plot!parameters0",
                "second": {"direction": "column", "first": "Plot!parameters1", "second": "Plot!parameters2"},
            },
            "second": {
                "direction": "row",
                "first": "Plot!uncertainty",
                "second": {
                    "direction": "column",
                    "first": "RawMessages!parameters",
                    "second": {"direction": "column", "first": "RawMessages!controls", "second": "RawMessages!events"},
                },
            },
        },
    }
    return {
        "configById": panels,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1.0},
        "layout": layout,
    }


def layout_topics(layout: dict[str, Any]) -> set[str]:
    """Every topic a layout names (a plot's paths, a message panel's topic, the diagnostics')."""
    out = set()
    for config in layout["configById"].values():
        for path in [p["value"] for p in config.get("paths", [])] + [config.get("topicPath", "")]:
            if path:
                out.add(path.split(".", 1)[0])
        if config.get("topicToRender"):
            out.add(config["topicToRender"])
    return out


def text(namespace: str = DEFAULT_NAMESPACE) -> str:
    return json.dumps(foxglove_layout(namespace), indent=2, ensure_ascii=False) + "\n"


if __name__ == "__main__":  # python -m phid_ros.stream.dashboard [NAMESPACE] > layout.json
    sys.stdout.write(text(sys.argv[1] if len(sys.argv) > 1 else DEFAULT_NAMESPACE))
