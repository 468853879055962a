"""What each test gave: one row per event of a recorder's day, from what identify took of it."""

from __future__ import annotations

from dataclasses import replace

import pytest

from phid_ros.controls.fit import ControlFit
from phid_ros.day_summary import day_summary
from phid_ros.ident.constraints import Constraints
from phid_ros.ident.pipeline import IdentifyOptions, identify
from phid_ros.model.parameters import TABLE1
from test.ident.test_field_circuit import CURVE, no_load_steps


def test_each_no_load_step_says_the_t_d0_its_field_circuit_gave() -> None:
    """Three no-load field steps as a controller's trend log carries them (the saturated TABLE 1
    machine, its curve held): each row is the step's test, at no load, the field held by the AVR,
    and the T'_d0 the field circuit took from it (within 2 % of the truth); an exciter's fitted
    reference step is said on its test's row."""
    # a trend log's channels: no stator currents, speed, rotor angle or P_m
    trend = frozenset({"i_d", "i_q", "omega", "delta", "p_m"})
    scs = [replace(s, absent=s.absent | trend) for s in no_load_steps({"up": 1.1, "deep": 0.6, "down": 0.9}, CURVE)]
    scs[1] = replace(scs[1], file_time_s=53.76)  # cut from a file's events: its time in the file
    opt = IdentifyOptions(baseline=False, validate=False, constraints=Constraints(saturation=CURVE))
    res = identify(scs, opt)
    assert "T_d0_prime" in res.determined_by
    exciter = ControlFit("SEXS", "exciter", {}, {}, {}, 0.0, None, None, True, "", references={"up": 0.1})
    rows = day_summary(res, {"exciter": exciter})
    assert [(r.test, r.state, r.held_by) for r in rows] == [(n, "no load", "AVR") for n in ("up", "deep", "down")]
    for r in rows:
        said = next(g for g in r.gave if g.endswith("(field circuit)"))
        assert float(said.split()[1]) == pytest.approx(TABLE1.T_d0_prime, rel=0.02)
    assert "exciter: reference step +0.1" in rows[0].gave and not any("exciter" in g for g in rows[1].gave)
    assert rows[0].event_s == pytest.approx(scs[0].k_event * scs[0].dt, abs=0.05)  # in its window
    assert rows[1].event_s == 53.76
