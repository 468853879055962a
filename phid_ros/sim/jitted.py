"""The base model's equations compiled as they are written, for the compiled play-in
(:mod:`phid_ros.sim.kernel`) and the effects' compiled terms (``PlantEffect.compiled``).

One compiled copy of each, taken from ``model/conventions`` and ``model/equations``; without
numba, the functions themselves (nothing compiled calls them then).
"""

from __future__ import annotations

from phid_ros.jit import maybe_jit
from phid_ros.model import conventions, equations

dq_of = maybe_jit(conventions.dq_of)
powers = maybe_jit(conventions.powers)
rotor_angle = maybe_jit(equations.rotor_angle)
swing = maybe_jit(equations.swing)
field_d = maybe_jit(equations.field_d)
field_q = maybe_jit(equations.field_q)
stator = maybe_jit(equations.stator)
airgap_power = maybe_jit(equations.airgap_power)
