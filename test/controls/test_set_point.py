"""The regulator's recorded set-point (``v_ref``) is the exciter's input, played as it moved.

A commissioning test moves the AVR's set-point by a ramp (a black start's build-up under a
set-point ramp, an operator's raise pulses), not only by a step: with the set-point recorded, the
exciter's fit plays it as recorded instead of sizing a step, and ``phid validate`` plays it too.
The data: the simulator's catalogue (its recorded V_t), E_fd made by SEXS from that V_t and a
set-point that ramps 0.03 pu over 3 s after the event.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from phid_ros.controls.cases import control_case, recorded_set_point
from phid_ros.controls.fit import ControlFit
from phid_ros.controls.identify import identify_controls
from phid_ros.controls.models import MODELS, ControlInputs
from phid_ros.ident.terminal import with_channels

SEXS = {"TA/TB": 0.2, "TB": 4.0, "K": 150.0, "TE": 0.08}


def _ramp(s, size: float = 0.03, over_s: float = 3.0):
    t = (np.arange(s.n) - s.k_event) * s.dt - 0.5
    return 1.0 + size * np.clip(t / over_s, 0.0, 1.0)


def _with_set_point(s, v_ref):
    """The scenario with E_fd as SEXS makes it from the recorded V_t and the set-point ``v_ref``
    (recorded, or left out: ``keep=False``)."""
    pre = s.pre_slice()
    v_t = np.asarray(s["v_t"], float)
    x = ControlInputs(s.dt, v_t - np.mean(v_t[pre]), np.zeros(s.n), v_ref - np.median(v_ref[pre]))
    model = MODELS["SEXS"]
    e_fd0 = float(np.mean(s["v_f"][pre]))
    e_fd = e_fd0 + model.response(model.completed({**model.defaults(), **SEXS}), x, 1.0)
    return with_channels(s, {"v_f": e_fd}, "E_fd from SEXS and the set-point")


def test_a_recorded_set_point_ramp_is_played_as_the_exciter_s_input(clean_scenarios) -> None:
    picked = [s for s in clean_scenarios if s.name.startswith(("S04", "S09", "S10", "V2"))]
    made = [_with_set_point(s, _ramp(s)) for s in picked]
    recorded = [replace(s, recorded={**s.recorded, "v_ref": _ramp(s)}) for s in made]
    case = control_case(recorded[0], "exciter")
    assert case is not None and case.stepped and case.reference == 1.0
    assert case.inputs.reference_step.max() == pytest.approx(0.03, abs=1e-12)  # the ramp, from its start
    assert recorded_set_point(made[0]) is None

    found = identify_controls(recorded, {"exciter": ["SEXS"]}, kinds=["exciter"])["exciter"]
    assert isinstance(found, ControlFit) and found.named, found
    for name, truth in SEXS.items():
        if found.identifiable.get(name):
            assert found.parameters[name] == pytest.approx(truth, rel=0.02), name
    assert found.identifiable["K"] and found.identifiable["TE"]
    assert found.references and set(found.references.values()) == {1.0}  # played as given, not sized

    # the same E_fd with the set-point not recorded: a step sized at the event cannot make a ramp
    blind = identify_controls(made, {"exciter": ["SEXS"]}, kinds=["exciter"])["exciter"]
    assert isinstance(blind, ControlFit)
    assert found.fit_rmse < 0.1 * blind.fit_rmse, (found.fit_rmse, blind.fit_rmse)


def test_validate_plays_the_recorded_set_point_into_the_unit_s_exciter(clean_scenarios) -> None:
    """``phid validate``'s play-in (open loop, from the recorded V_t) with the unit's SEXS: E_fd as
    the recording made it where the set-point is recorded, said in the event's notes; without
    it the step sized at the event misses the ramp."""
    from phid_ros.controls.unit_validation import control_of, validate_unit
    from phid_ros.model.parameters import TABLE1

    s = next(s for s in clean_scenarios if s.name.startswith("S09"))
    made = _with_set_point(s, _ramp(s))
    recorded = replace(made, recorded={**made.recorded, "v_ref": _ramp(s)})
    # its limits out of reach: the E_fd above is made without them
    exciter = {"exciter": control_of("SEXS", {**MODELS["SEXS"].defaults(), **SEXS, "EMIN": -20.0, "EMAX": 20.0})}

    def e_fd_check(scenario):
        v = validate_unit([scenario], TABLE1, exciter, 50.0, "the unit", close_loops=False).scenarios[0]
        return next(c for c in v.checks if c.channel == "v_f"), v.notes

    given, notes = e_fd_check(recorded)
    assert "exciter reference: the recorded set-point v_ref, as it moved" in notes, notes
    assert given.passed and given.max_error < 0.02 * given.band, given  # the fit grid's smoothed V_t times K
    blind, blind_notes = e_fd_check(made)
    assert not any("set-point" in n for n in blind_notes)
    assert blind.max_error > 10 * given.max_error, (blind.max_error, given.max_error)
