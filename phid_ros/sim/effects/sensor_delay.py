"""A sensor stream that reports late: the play-in re-times the measurements, the equations are the plant's."""

from __future__ import annotations

from typing import Any

import numpy as np

from phid_ros.io.topics import STREAMS, STREAMS_BY_NAME
from phid_ros.sim.effects.base import Array, EffectParameter, PlantEffect, register


@register
class SensorDelay(PlantEffect):
    """A fixed latency on one sensor stream (e.g. PMU angles reported late)."""

    name = "sensor_delay"
    parameters = (
        EffectParameter("stream", "pmu", "", "the delayed stream", choices=tuple(s.name for s in STREAMS)),
        EffectParameter("delay_ms", 10.0, "ms", "latency", 1.0, 100.0),
    )

    def on_measurements(self, measured: dict[str, Array], dt: float) -> dict[str, Array]:
        k = int(round(self["delay_ms"] * 1e-3 / dt))  # the simulated latency is whole samples
        out = dict(measured)
        for c in STREAMS_BY_NAME[self["stream"]].channels:
            x = measured[c]
            out[c] = np.concatenate((np.full(k, x[0]), x[:-k])) if k else x
        return out

    def delays(self) -> dict[str, Any]:
        return {c: self["delay_ms"] * 1e-3 for c in STREAMS_BY_NAME[self["stream"]].channels}

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        return {}  # the play-in re-times the measurements; the equations are the plant's
