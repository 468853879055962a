"""The open-circuit curve in the planning form from no-load plateaus (ident/open_circuit_curve.py),
on no-load field steps of a saturated machine (S(1.0) 0.1, S(1.2) 0.4, GENSAL's form) recorded
with its field current, as a controller's trend log carries them."""

import math

import pytest

from phid_ros.ident.field_circuit import FieldCurrentBase
from phid_ros.ident.open_circuit_curve import no_load_plateaus, open_circuit_curve
from test.ident.test_field_circuit import CURVE, I_FD_BASE, no_load_steps

# the recorded I_f is X_ad I_fd x I_FD_BASE: the air-gap line as the truth has it
TRUE_LINE = FieldCurrentBase(1.0 / I_FD_BASE, True, "the look-alike's own", math.nan)


def test_the_curve_through_plateaus_up_to_1_2_pu_gives_both_points_of_the_planning_form() -> None:
    scs = no_load_steps({"a": 0.85, "b": 0.95, "c": 1.1, "d": 1.3, "e": 1.55}, CURVE)
    curve = open_circuit_curve(TRUE_LINE, scs, 0.005)
    assert curve is not None
    assert max(p.v_t for p in curve.points) > 1.18
    assert curve.s10.identifiable and curve.s10.value == pytest.approx(CURVE[0], abs=0.01)
    assert curve.s12.identifiable and curve.s12.value == pytest.approx(CURVE[1], abs=0.03)
    assert curve.worst < 0.01  # the form is the machine's: it passes through every plateau
    # the line's own uncertainty is in every S: (1 + S) x its relative std at least
    assert curve.s10.std >= (1 + curve.s10.value) * 0.005


def test_a_curve_measured_to_rated_voltage_withholds_s_1_2_and_says_what_the_form_gives() -> None:
    scs = no_load_steps({"a": 0.85, "b": 0.9, "c": 0.95, "d": 1.02}, CURVE)
    curve = open_circuit_curve(TRUE_LINE, scs)
    assert curve is not None
    assert curve.s10.identifiable and curve.s10.value == pytest.approx(CURVE[0], abs=0.015)
    assert not curve.s12.identifiable and "not measured" in curve.s12.note
    assert curve.worst < 0.01


def test_plateaus_of_one_level_in_one_file_are_one_point() -> None:
    scs = no_load_steps({"a": 0.9, "b": 0.9}, CURVE)  # two files, each a step from 1.0 pu to one level
    points = no_load_plateaus(scs)
    assert len(points) == 4  # each file's 1.0 pu plateau and its own lower one
    assert sorted(p[3] for p in points) == ["", "", "falling", "falling"]


def test_without_a_determined_air_gap_line_no_curve_is_given() -> None:
    scs = no_load_steps({"a": 0.9}, CURVE)
    assert open_circuit_curve(FieldCurrentBase(1.0, False, "a bound", math.nan), scs) is None
