"""Armature resistance: the base model has R_a = 0."""

from __future__ import annotations

from typing import Any

from phid_ros.sim.effects.base import EffectParameter, PlantEffect, register


@register
class StatorResistance(PlantEffect):
    """Armature resistance R_a (the base model has R_a = 0)."""

    name = "stator_resistance"
    parameters = (EffectParameter("r_a", 0.005, "pu", "stator resistance", 0.001, 0.02, absent=0.0),)

    def configure(self, plant: Any) -> None:
        plant.r_a = self["r_a"]

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        return {}  # the plant's r_a, which the kernel reads
