"""Physical effects the fourth-order model leaves out, switchable in the plant (off by default).

A small library in the shape of pysindy's candidate terms and ANDES's models: each
effect is one class with its parameter data (defaults, units, realistic ranges)
declared apart from what it does, registered by name, so a new effect is added
without touching the others. An effect acts through a few hooks, each a no-op
by default:

- ``configure(plant)``: change plant constants (stator resistance);
- ``flux_loss_d(e_q)``: an extra term subtracted in T'_d0 dE'_q/dt (saturation);
- ``on_measurements(measured, dt)``: act on the sensor outputs (a delayed stream).

Implemented here: ``stator_resistance``, ``magnetic_saturation``, ``sensor_delay``.
Not yet: ``subtransient_dynamics`` and ``shaft_torsion`` (they need extra states).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import SimulationError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class EffectParameter:
    name: str
    default: Any
    unit: str
    description: str
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()


class PlantEffect:
    """Base class: parameter handling and no-op hooks."""

    name: ClassVar[str] = ""
    parameters: ClassVar[tuple[EffectParameter, ...]] = ()

    def __init__(self, **values: Any) -> None:
        known = {p.name: p for p in self.parameters}
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise SimulationError(f"effect {self.name}: unknown parameter(s) {unknown}; known: {sorted(known)}")
        self.values: dict[str, Any] = {}
        for p in self.parameters:
            v = values.get(p.name, p.default)
            if p.choices:
                if v not in p.choices:
                    raise SimulationError(f"effect {self.name}: {p.name}={v!r} not one of {p.choices}")
            else:
                v = float(v)
                if (p.low is not None and v < p.low) or (p.high is not None and v > p.high):
                    raise SimulationError(
                        f"effect {self.name}: {p.name}={v:g} {p.unit} outside [{p.low:g}, {p.high:g}] (realistic range)"
                    )
            self.values[p.name] = v

    def __getitem__(self, key: str) -> Any:
        return self.values[key]

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, **self.values}

    # hooks ---------------------------------------------------------------------------------
    def configure(self, plant: Any) -> None:
        return None

    def flux_loss_d(self, e_q: Array) -> Array | float:
        return 0.0

    def on_measurements(self, measured: dict[str, Array], dt: float) -> dict[str, Array]:
        return measured


REGISTRY: dict[str, type[PlantEffect]] = {}


def register(cls: type[PlantEffect]) -> type[PlantEffect]:
    REGISTRY[cls.name] = cls
    return cls


@register
class StatorResistance(PlantEffect):
    """Armature resistance R_a (the base model has R_a = 0)."""

    name = "stator_resistance"
    parameters = (EffectParameter("r_a", 0.005, "pu", "stator resistance", 0.001, 0.02),)

    def configure(self, plant: Any) -> None:
        plant.r_a = float(self["r_a"])


@register
class MagneticSaturation(PlantEffect):
    """Open-circuit saturation of the d axis: T'_d0 dE'_q/dt gains -S_E(E'_q) E'_q.

    S_E(E) = A exp(B E), fitted through the usual two points S(1.0) and S(1.2).
    """

    name = "magnetic_saturation"
    parameters = (
        EffectParameter("s10", 0.08, "pu", "saturation factor at 1.0 pu", 0.02, 0.2),
        EffectParameter("s12", 0.35, "pu", "saturation factor at 1.2 pu", 0.1, 0.8),
    )

    def __init__(self, **values: Any) -> None:
        super().__init__(**values)
        if not self["s12"] > self["s10"]:
            raise SimulationError("effect magnetic_saturation: s12 must exceed s10")
        self.b = float(np.log(self["s12"] / self["s10"]) / 0.2)
        self.a = float(self["s10"] * np.exp(-self.b))

    def flux_loss_d(self, e_q: Array) -> Array:
        return self.a * np.exp(self.b * e_q) * e_q


@register
class SensorDelay(PlantEffect):
    """A fixed latency on one sensor stream (e.g. PMU angles reported late)."""

    name = "sensor_delay"
    parameters = (
        EffectParameter("stream", "pmu", "", "the delayed stream", choices=("pt_ct", "encoder", "pmu", "excitation")),
        EffectParameter("delay_ms", 10.0, "ms", "latency", 1.0, 100.0),
    )

    def on_measurements(self, measured: dict[str, Array], dt: float) -> dict[str, Array]:
        from phid_ros.io.topics import STREAMS_BY_NAME

        k = int(round(self["delay_ms"] * 1e-3 / dt))
        out = dict(measured)
        for c in STREAMS_BY_NAME[self["stream"]].channels:
            x = measured[c]
            out[c] = np.concatenate((np.full(k, x[0]), x[:-k])) if k else x
        return out


def parse_effect(spec: str) -> PlantEffect:
    """``NAME`` or ``NAME=k=v,k=v`` (the ``phid simulate --effect`` syntax) -> an effect."""
    name, _, rest = spec.partition("=")
    cls = REGISTRY.get(name.strip())
    if cls is None:
        planned = {"subtransient_dynamics", "shaft_torsion"}
        hint = " (planned, not implemented yet)" if name.strip() in planned else ""
        raise SimulationError(f"unknown effect {name.strip()!r}{hint}; available: {', '.join(sorted(REGISTRY))}")
    values: dict[str, Any] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, sep, value = item.partition("=")
        if not sep:
            raise SimulationError(f"effect {name}: {item!r} is not key=value")
        values[key.strip()] = value.strip()
    return cls(**values)


def effects_summary(effects: Mapping[str, PlantEffect] | list[PlantEffect]) -> list[dict[str, Any]]:
    items = effects.values() if isinstance(effects, Mapping) else effects
    return [e.as_dict() for e in items]
