"""The no-load tests played with what identify found: T'_d0 on the held curve, on open circuit.

On the project's own simulator: TABLE 1's machine with S(1.0) 0.1, S(1.2) 0.4, no-load field
steps recorded as an excitation controller does (E_fd and I_fd on bases of their own).
"""

from __future__ import annotations

import dataclasses

import pytest

from phid_ros.controls.no_load_playback import no_load_playback
from phid_ros.ident.constraints import Constraints
from phid_ros.ident.field_circuit import field_circuit, machine_field
from phid_ros.model.parameters import TABLE1
from test.ident.test_field_circuit import CURVE, no_load_steps


@pytest.fixture(scope="module")
def day():
    scs = no_load_steps({"up": 1.1, "down": 0.9}, CURVE)
    field = machine_field(scs, CURVE)
    assert field is not None
    return field.applied(scs, "E_fd on the machine's base"), field_circuit(scs, CURVE).T_d0_prime


def test_the_identified_t_d0_on_the_curve_plays_the_no_load_steps_back(day) -> None:
    on_base, t_d0 = day
    assert t_d0.value == pytest.approx(TABLE1.T_d0_prime, rel=0.02)
    held = Constraints(saturation=CURVE)
    result, why = no_load_playback(on_base, {"T_d0_prime": t_d0}, held, {}, 50.0)
    assert result is not None and not why
    assert "on open circuit" in result.unit and "E_fd as recorded" in result.unit
    checks = {(s.scenario, c.channel): c for s in result.scenarios for c in s.checks}
    assert set(checks) == {("up", "v_t"), ("down", "v_t")}  # E_fd played as recorded: nothing to check of it
    for c in checks.values():
        assert c.passed and c.max_error < 0.004, c  # the sensors' noise and the report rate's resampling
    # a T'_d0 30 % long misses the same steps by twice as much and more (0.0061 against 0.0028 pu)
    wrong = dataclasses.replace(t_d0, value=1.3 * t_d0.value)
    result, _ = no_load_playback(on_base, {"T_d0_prime": wrong}, held, {}, 50.0)
    assert result is not None
    for s in result.scenarios:
        [c] = s.checks
        assert c.max_error > 2 * checks[(s.scenario, "v_t")].max_error


def test_without_a_curve_or_a_t_d0_nothing_is_played(day) -> None:
    on_base, t_d0 = day
    result, why = no_load_playback(on_base, {"T_d0_prime": t_d0}, Constraints(), {}, 50.0)
    assert result is None and "no open-circuit curve held (--saturation)" in why
    withheld = dataclasses.replace(t_d0, identifiable=False)
    result, why = no_load_playback(on_base, {"T_d0_prime": withheld}, Constraints(saturation=CURVE), {}, 50.0)
    assert result is None and "T'_d0 is not identified" in why
