"""Physical effects the fourth-order model leaves out, switchable in the plant (off by default).

A small library in the shape of pysindy's candidate terms and ANDES's models: each effect is one
module here, one class with its parameter data (defaults, units, realistic ranges) declared apart
from what it does, its equations as plain functions, and the compiled form of those equations
(:class:`~phid_ros.sim.effects.base.Compiled`) that the play-in's kernel is built from. Every module
of this package is imported with it, so a new effect is a new file: registered by its class's
``@register``, taken by ``phid simulate --effect``, the diagnosis's candidates, the compiled
play-in and the reference pages, without an edit anywhere else. :mod:`~phid_ros.sim.effects.base`
has the hooks an effect acts through.

Effects: ``stator_resistance``, ``magnetic_saturation``, ``sensor_delay``,
``subtransient_dynamics``, ``shaft_torsion``.
"""

from __future__ import annotations

import importlib
import pkgutil

from phid_ros.sim.effects.base import (
    REGISTRY,
    Compiled,
    EffectParameter,
    PlantEffect,
    RotorContext,
    effects_summary,
    leakage_default,
    parse_effect,
    register,
)

__all__ = [
    "REGISTRY",
    "Compiled",
    "EffectParameter",
    "PlantEffect",
    "RotorContext",
    "effects_summary",
    "leakage_default",
    "parse_effect",
    "register",
]

# each module registers its effect as it is imported; in name order, so the registry's order
# (the order of the compiled play-in's terms) is the same on every machine
for _module in sorted(m.name for m in pkgutil.iter_modules(__path__)):
    if _module != "base":
        importlib.import_module(f"{__name__}.{_module}")
