"""GENROU's damped axis and the fourth-order axis that plays its slow part."""

from __future__ import annotations

import numpy as np
import pytest

from phid_ros.errors import ParameterError
from phid_ros.model.damper_equivalent import DamperedAxis

# ANDES's GENROU of the corpus's andes-exst1-other set, q axis: X'' far below X'_q
AXIS = DamperedAxis(x=1.7, x_t=0.6, x_pp=0.3, x_l=0.15, t_0=0.8, t_0pp=0.05)


def operational_reactance(ax: DamperedAxis, s: complex) -> complex:
    """-psi/I of GENROU's axis at ``s``, the field voltage held: the two rotor equations solved
    as written (SubtransientDynamics), not through their poles."""
    a = ax.x_t - ax.x_l
    g = (ax.x_pp - ax.x_l) / a
    load = (ax.x - ax.x_t) * (ax.x_t - ax.x_pp) / a**2
    # unknowns E', psi_k for I = 1
    lhs = np.array([[1 + s * ax.t_0 + load, -load], [-1.0, 1 + s * ax.t_0pp]], dtype=complex)
    rhs = np.array([-(ax.x - ax.x_t) + load * a, -a], dtype=complex)
    e, psi_k = np.linalg.solve(lhs, rhs)
    return -(g * e + (1 - g) * psi_k - ax.x_pp)


def test_the_slow_pole_and_its_drop_are_those_of_genrou_s_operational_reactance() -> None:
    x_t, t_0 = AXIS.fourth_order()
    # the other pole of the open-circuit characteristic T'T'' s^2 + (T' + T'' + L T'') s + 1
    load = (AXIS.x - AXIS.x_t) * (AXIS.x_t - AXIS.x_pp) / (AXIS.x_t - AXIS.x_l) ** 2
    roots = np.roots([AXIS.t_0 * AXIS.t_0pp, AXIS.t_0 + AXIS.t_0pp + load * AXIS.t_0pp, 1.0])
    assert -1 / roots.real.max() == pytest.approx(t_0, rel=1e-12)
    t_fast = -1 / roots.real.min()
    for s in (0.0, 0.3, 2.0, 15.0, 1j, 40 + 5j):
        two_poles = AXIS.x_pp + (AXIS.x - x_t) / (1 + s * t_0) + (x_t - AXIS.x_pp) / (1 + s * t_fast)
        assert operational_reactance(AXIS, s) == pytest.approx(two_poles, rel=1e-12, abs=1e-12), s
    # the damper's load makes the slow circuit slower and its drop larger than the constants say
    assert t_0 > AXIS.t_0 and x_t < AXIS.x_t
    assert (x_t, t_0) == pytest.approx((0.5175, 0.8864), abs=1e-4)


def test_an_inert_damper_leaves_the_axis_as_written() -> None:
    inert = DamperedAxis(x=2.54, x_t=0.5, x_pp=0.5, x_l=0.15, t_0=1.437, t_0pp=0.03)
    assert not inert.damper_acts and inert.fourth_order() == (0.5, 1.437)
    # another X' above X'' makes the damper act: its constants are solved for, not copied
    moved = inert.for_fourth_order(0.55, 1.2)
    assert moved.damper_acts and moved.fourth_order() == pytest.approx((0.55, 1.2), rel=1e-9)


def test_the_classical_constants_that_play_a_fourth_order_axis() -> None:
    classical = AXIS.for_fourth_order(0.5175, 0.8864)
    assert classical.fourth_order() == pytest.approx((0.5175, 0.8864), rel=1e-9)
    # X, X'', X_l and T''_0 are kept: only X' and T'_0 move
    assert (classical.x, classical.x_pp, classical.x_l, classical.t_0pp) == (1.7, 0.3, 0.15, 0.05)
    back = AXIS.for_fourth_order(*AXIS.fourth_order())
    assert (back.x_t, back.t_0) == pytest.approx((AXIS.x_t, AXIS.t_0), rel=1e-9)


def test_what_no_genrou_axis_plays_is_refused() -> None:
    with pytest.raises(ParameterError, match=r"fourth-order X'=0.25 must lie between X''=0.3 and X=1.7"):
        AXIS.for_fourth_order(0.25, 0.8)
    with pytest.raises(ParameterError, match=r"0 < X_l < X'' <= X' < X"):
        DamperedAxis(x=1.7, x_t=0.6, x_pp=0.7, x_l=0.15, t_0=0.8, t_0pp=0.05)
    with pytest.raises(ParameterError, match="time constants must be positive"):
        DamperedAxis(x=1.7, x_t=0.6, x_pp=0.3, x_l=0.15, t_0=0.8, t_0pp=0.0)
