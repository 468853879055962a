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
    adopted = RecalibrationOutcome(True, "ok", None, None, ["e1"], T0, 0.1)
    named = diagnostics_message(types, T0, health, adopted, unit="/plant/unit3")
    assert [(s.name, s.hardware_id) for s in named.status] == [
        ("phid/plant/unit3: pt_ct stream", "plant/unit3"),
        ("phid/plant/unit3: recalibration", "plant/unit3"),
    ]
    # the recalibration's level is the outcome's, not read back from its sentence: adopted OK, a run
    # that raised ERROR, a kept set or a partial one WARN (whatever their wording says)
    failed = RecalibrationOutcome(False, "ok? no: it raised", None, None, ["e1"], T0, 0.1, failed=True)
    kept = RecalibrationOutcome(False, "kept last good set: recalibration failed once", None, None, ["e1"], T0, 0.1)
    for outcome, level in ((adopted, 0), (failed, 2), (kept, 1)):
        [_, recal] = diagnostics_message(types, T0, health, outcome).status
        assert (recal.level, recal.message) == (level, outcome.status)
    plain = diagnostics_message(types, T0, health, None)
    assert [(s.name, s.hardware_id) for s in plain.status] == [("phid: pt_ct stream", "generator")]


def test_before_any_set_a_partial_run_publishes_what_it_determined_and_only_that(types: dict) -> None:
    """A recorder without the rotor's channels determines some parameters, never all eight: the
    message names the determined ones alone, the status names the rest as withheld."""
    from phid_ros.ident.results import Estimate

    determined = {"X_d": Estimate(2.54, 0.006), "T_d0_prime": Estimate(1.44, 0.005)}
    why = "withheld H, D, X_q, X_d_prime, X_q_prime, T_q0_prime: not determined ..."
    status = f"partial set: {why}"
    partial = RecalibrationOutcome(False, status, None, None, ["e1"], T0, 0.1, determined, why=why)
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


def test_a_window_carries_the_recorder_s_field_current_to_the_recalibration_node(types: dict) -> None:
    """The ingest node's window message carries i_fd, v_r, v_s where the recorder kept them (empty
    otherwise), back to the same float64 values; its samples are judged on the deployment's
    declared channels (a trend log's absent rotor channels made every window "stale" before)."""
    from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings

    w = _window(T0)
    i_fd = np.linspace(0.51, 0.64, len(w.t_ns))
    w.recorded = {"i_fd": i_fd, "v_r": i_fd * 2.5}
    msg = _sent(types, w)
    assert len(msg.v_s) == 0  # type: ignore[attr-defined]
    back = window_from_message(msg)
    assert set(back.recorded) == {"i_fd", "v_r"}
    assert np.array_equal(back.recorded["i_fd"], i_fd) and np.array_equal(back.recorded["v_r"], i_fd * 2.5)
    w.values[:, CHANNELS.index("omega")] = np.nan  # a recorder without the rotor's speed
    trend_log = MonitorPipeline(PipelineSettings(not_recorded=frozenset({"omega"}), auto_recalibrate=False))
    ten_channels = MonitorPipeline(PipelineSettings(auto_recalibrate=False))
    try:
        kept = trend_log.add_window(window_from_message(_sent(types, w))).windows[0]
        assert kept.usable and trend_log.store.latest()[0].recorded["i_fd"].tolist() == i_fd.tolist()
        refused = ten_channels.add_window(window_from_message(_sent(types, w))).windows[0]
        assert not refused.usable and "omega" in refused.reason
    finally:
        trend_log.close()
        ten_channels.close()


def _sent(types: dict, w: EventWindow) -> object:
    """``w`` as the ingest node publishes it."""
    return next(iter(emit(types, Outputs(windows=[w]), {"windows"}))).message


def test_each_recalibration_publishes_its_control_systems_beside_the_machine(types: dict) -> None:
    """The exciter fitted at a recalibration goes out on control_parameters: the model named, its
    constants with what the recordings determined (a ceiling reached), or why none is named."""
    from phid_ros.controls.fit import ControlFit

    fit = ControlFit(
        "SEXS",
        "exciter",
        {"TA_TB": 0.1, "TB": 10.0, "K": 200.0, "TE": 0.05, "EMIN": None, "EMAX": 5.3},
        {"TA_TB": None, "TB": None, "K": 12.0, "TE": 0.01, "EMIN": None, "EMAX": 0.02},
        {"TA_TB": False, "TB": False, "K": True, "TE": True, "EMIN": False, "EMAX": True},
        0.044,
        None,
        0.2,
        True,
        "SEXS: fit error 0.044 pu against 0.2 pu without control action",
        limits={"EMAX": 5.3},
    )
    r = RecalibrationOutcome(False, "partial set: ...", None, None, ["e1"], T0, 0.1)
    r.controls = {"exciter": fit, "stabiliser": "not identified: no scenario with p_e and v_s to fit"}
    exciter, stabiliser = [p.message for p in emit(types, Outputs(recalibrations=[r]), {"controls"})]
    assert (exciter.kind, exciter.model, exciter.fitted_model) == ("exciter", "SEXS", "SEXS")
    assert list(exciter.names) == ["TA_TB", "TB", "K", "TE", "EMIN", "EMAX"]
    assert list(exciter.values)[2:4] == [200.0, 0.05] and np.isnan(exciter.values[4])
    assert list(exciter.identifiable) == [False, False, True, True, False, True]
    assert list(exciter.limits_reached) == ["EMAX"] and exciter.fit_rmse == 0.044
    assert list(exciter.event_ids) == ["e1"] and exciter.header.stamp.sec == T0 // NS
    assert stabiliser.model == "" and stabiliser.why.startswith("not identified") and len(stabiliser.names) == 0
