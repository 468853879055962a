"""The one outputs -> messages mapping (phid_ros.stream.emit), used by the nodes and by replay."""

from __future__ import annotations

import numpy as np
import pytest

from phid_ros.io.msg_schemas import typestore
from phid_ros.model.channels import CHANNELS
from phid_ros.model.conventions import NS
from phid_ros.model.parameters import GeneratorParameters
from phid_ros.stream.detector import Event, EventWindow, event_id
from phid_ros.stream.emit import ALL_KEYS, emit
from phid_ros.stream.messages import window_from_message
from phid_ros.stream.pipeline import Outputs
from phid_ros.stream.recalibration import RecalibrationOutcome

T0 = 1_700_000_000 * NS
PERIOD = NS // 100


def _window(t_ns: int, usable: bool = True, reason: str = "") -> EventWindow:
    ev = Event(
        event_id=event_id("torque_step", t_ns),
        kind="torque_step",
        inception_ns=t_ns,
        clearing_ns=0,
        severity=0.1,
        v_prefault=1.0,
        segment=0,
    )
    n = 200
    values = np.tile(np.linspace(0.5, 1.5, len(CHANNELS)), (n, 1))
    t = t_ns - NS + np.arange(n, dtype=np.int64) * PERIOD
    return EventWindow(t_ns=t, values=values, period_ns=PERIOD, event=ev, usable=usable, reason=reason)


@pytest.fixture(scope="module")
def types() -> dict:
    return typestore().types


def test_every_output_becomes_one_message_at_its_stream_time(types: dict) -> None:
    good, cut = _window(T0), _window(T0 + 30 * NS, usable=False, reason="the clock jumped")
    rejected = RecalibrationOutcome(False, "kept last good set: too few events", GeneratorParameters(), None, [], T0, 0)
    out = Outputs(events=[good.event, cut.event], windows=[good, cut], recalibrations=[rejected])
    done = emit(types, out)
    keys = [(p.key, p.log_ns) for p in done]
    # both events are said; only the usable window goes out, stamped at its last sample
    assert keys == [
        ("events", T0),
        ("events", T0 + 30 * NS),
        ("windows", int(good.t_ns[-1])),
        ("parameters", T0),
    ]
    assert done.notes[0].startswith(f"event {cut.event.event_id} (torque_step) window not published")
    assert "the clock jumped" in done.notes[0]
    assert done.notes[1] == "kept last good set: too few events"
    # the window's samples arrive as they were cut
    back = window_from_message(done.messages[2].message)
    np.testing.assert_array_equal(back.values, good.values)
    np.testing.assert_array_equal(back.t_ns, good.t_ns)


def test_a_node_gets_only_its_topics(types: dict) -> None:
    w = _window(T0)
    out = Outputs(events=[w.event], windows=[w])
    assert [p.key for p in emit(types, out, {"windows"})] == ["windows"]
    assert list(emit(types, out, {"parameters", "hamiltonian"})) == []
    with pytest.raises(ValueError, match="no output topic"):
        emit(types, out, {"diagnostics"})
    assert "diagnostics" not in ALL_KEYS


def test_diagnostics_name_their_unit_so_a_plant_s_monitors_group_apart(types: dict) -> None:
    """Every unit's monitor publishes on the one /diagnostics: each status carries its unit as the
    hardware id and the name's prefix; without a unit the names stay as they were."""
    from phid_ros.stream.align import StreamHealth
    from phid_ros.stream.messages import diagnostics_message

    health = {"pt_ct": StreamHealth("pt_ct", expected_rate_hz=1000.0)}
    named = diagnostics_message(types, T0, health, "ok", unit="/plant/unit3")
    assert [(s.name, s.hardware_id) for s in named.status] == [
        ("phid/plant/unit3: pt_ct stream", "plant/unit3"),
        ("phid/plant/unit3: recalibration", "plant/unit3"),
    ]
    plain = diagnostics_message(types, T0, health, None)
    assert [(s.name, s.hardware_id) for s in plain.status] == [("phid: pt_ct stream", "generator")]


def test_before_any_set_a_partial_run_publishes_what_it_determined_and_only_that(types: dict) -> None:
    """A recorder without the rotor's channels determines some parameters, never all eight: the
    message names the determined ones alone, the status names the rest as withheld."""
    from phid_ros.ident.results import Estimate

    determined = {"X_d": Estimate(2.54, 0.006), "T_d0_prime": Estimate(1.44, 0.005)}
    status = "partial set: withheld H, D, X_q, X_d_prime, X_q_prime, T_q0_prime: not determined ..."
    partial = RecalibrationOutcome(False, status, None, None, ["e1"], T0, 0.1, determined)
    [msg] = [p.message for p in emit(types, Outputs(recalibrations=[partial]))]
    assert list(msg.names) == ["X_d", "T_d0_prime"]
    assert list(msg.values) == [2.54, 1.44] and list(msg.std_dev) == [0.006, 0.005]
    assert list(msg.identifiable) == [True, True] and msg.status == status
    assert partial.said() == (
        "partial set published: X_d, T'_d0",
        "withheld H, D, X_q, X'_d, X'_q, T'_q0: not determined ...",  # the status's, in the paper's symbols
    )
    # nothing determined and no set in force: nothing to publish
    empty = RecalibrationOutcome(False, "kept last good set: incomplete result (...)", None, None, [], T0, 0.1)
    assert list(emit(types, Outputs(recalibrations=[empty]))) == []
