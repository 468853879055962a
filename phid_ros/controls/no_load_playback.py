"""The day's no-load tests played with what ``phid identify`` found, before any record exists.

A recorder's channel set seldom determines H, D or the q axis, so identify cannot simulate its
on-line tests (``phid validate`` does, on a record that supplies them). On open circuit no
stator current flows: the swing and the q axis are idle, and the terminal voltage answers the
field through T'_d0 and the open-circuit curve alone. So the no-load events, the exciter's loop
closed through the machine, are played with the identified T'_d0 on the held curve and checked
as ``phid validate`` checks them (V_t and E_fd within MOD-026's bands): the plant engineer sees
the identified unit against the recording on the day's own tests.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from phid_ros.controls.fit import ControlFit
from phid_ros.controls.unit_validation import (
    CHANNELS,
    Control,
    ScenarioCheck,
    UnitValidation,
    control_of,
    validate_unit,
)
from phid_ros.ident.constraints import Constraints
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.terminal import at_no_load
from phid_ros.model.parameters import GeneratorParameters
from phid_ros.sim.effects import PlantEffect
from phid_ros.sim.effects.magnetic_saturation import MagneticSaturation


def no_load_playback(
    on_base: Sequence[ScenarioData],
    estimates: Mapping[str, Estimate],
    constraints: Constraints,
    controls: Mapping[str, ControlFit | str],
    f_nominal_hz: float,
) -> tuple[UnitValidation | None, str]:
    """The no-load events of ``on_base`` (E_fd on the machine's base, as the exciter was fitted)
    played on open circuit with the identified T'_d0 on the held curve and the named exciter;
    or None and why not."""
    no_load = [s for s in on_base if at_no_load(s) and s.has("v_t", "v_f")]
    if not no_load:
        return None, "no no-load test to play"
    t_d0 = estimates.get("T_d0_prime")
    if t_d0 is None or not (t_d0.identifiable or "T_d0_prime" in constraints.fixed):
        return None, "T'_d0 is not identified: the no-load tests are not played"
    curve = constraints.saturation
    if curve is None:
        return None, "no open-circuit curve held (--saturation): the no-load tests are not played"
    # the others at their declared defaults: idle on open circuit, they are not what is judged
    params = GeneratorParameters(T_d0_prime=t_d0.value)
    played: dict[str, Control] = {}
    exciter = controls.get("exciter")
    if isinstance(exciter, ControlFit) and exciter.named:
        played["exciter"] = control_of(exciter.model, {n: v for n, v in exciter.parameters.items() if v is not None})
    effects: list[tuple[type[PlantEffect], Mapping[str, Any]]] = [
        (MagneticSaturation, {"s10": curve[0], "s12": curve[1], "form": "gensal", "curve": "quadratic"})
    ]
    described = (
        f"the identified machine on open circuit (T'_d0 {t_d0.value:.4g} s, S(1.0) = {curve[0]:g}, "
        f"S(1.2) = {curve[1]:g}; no dampers: the day did not determine them)"
        + (f" + {played['exciter'].model.name}" if played else ", E_fd as recorded")
    )
    result = validate_unit(no_load, params, played, f_nominal_hz, described, effects)
    for sc, scenario in zip(result.scenarios, no_load):
        sc.notes.extend(_where_missed(sc, scenario.k_event * scenario.dt))
    result.notes.insert(
        0,
        "on open circuit no stator current flows: H, D, the q axis, X_d and X'_d do not move V_t, and are "
        "not what these checks judge",
    )
    return result, ""


SUBTRANSIENT_S = 0.2  # a miss that ends this soon after the event is the dampers' part of the response


def _where_missed(sc: ScenarioCheck, t_event: float) -> list[str]:
    """Where each failed check leaves its band, after the event: a miss inside the first
    ``SUBTRANSIENT_S`` is the dampers' part, which this play does not have."""
    out = []
    for c in sc.checks:
        if c.passed:
            continue
        over = sc.t[np.abs(sc.simulated[c.channel] - sc.recorded[c.channel]) > c.band] - t_event
        if not over.size:
            continue
        where = f"{CHANNELS[c.channel][1]} leaves its band from {over.min():.3f} to {over.max():.3f} s after the event"
        if 0.0 <= over.min() and over.max() <= SUBTRANSIENT_S:
            where += ": the subtransient part, the dampers' (not simulated here)"
        out.append(where)
    return out
