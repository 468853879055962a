"""The monitor checks the unit's record on file against every event it sees (issue 74).

The shipped catalogue bag replayed with the machine's own record (the simulator's parameters,
written by ``phid export``) and with a record of the wrong machine (X'_d 20 % off): the verdicts
are ``phid validate``'s on the same windows to the last digit, the own record stays OK, the
wrong one is raised as the events show it and X'_d is named as drifting."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from phid_ros.controls.unit_validation import ChannelCheck
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1, GeneratorParameters
from phid_ros.stream.record_check import ERROR, OK, WARN, EventVerdict, RecordCheck, RecordCheckSettings

ROOT = Path(__file__).resolve().parents[2]
CATALOGUE = ROOT / "bags" / "catalogue"
P_M0 = 0.8  # the catalogue's operating point (phid identify's operating_point)


def record_of(tmp_path: Path, name: str, params: GeneratorParameters) -> Path:
    """The unit's .dyr as phid export writes it from an identification of ``params``."""
    from phid_ros.cli.main import main

    doc = {
        "parameters": params.as_dict(),
        "identifiable": {n: True for n in PARAMETER_NAMES},
        "f_nominal_hz": 50.0,
        "base_mva": 1000.0,
        "operating_point": {"p_m_pu": P_M0},
    }
    (tmp_path / f"{name}.json").write_text(json.dumps(doc))
    out = tmp_path / f"{name}.dyr"
    assert main(["export", str(tmp_path / f"{name}.json"), "--format", "psse-dyr", "--out", str(out)]) == 0
    return out


def replayed(dyr: Path, bag: Path, store: str = ":memory:"):
    from phid_ros.api import record_check
    from phid_ros.io.bags.recordings import read_recording
    from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings
    from phid_ros.stream.replay import replay

    pipeline = MonitorPipeline(PipelineSettings(store_path=store))
    pipeline.record_check = record_check(dyr)
    try:
        return replay(read_recording(bag), pipeline), pipeline
    finally:
        pipeline.close()


@pytest.fixture(scope="module")
def records(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """The own record, the wrong one, and the catalogue without its scenario markers: a plant's
    recording, whose events phid validate cuts as the monitor cuts them (with markers, validate
    takes the test sheet's 10 s spans where the monitor's windows run on to the next event)."""
    from phid_ros.io.bags.recordings import read_recording, write_recording
    from phid_ros.io.recording import Recording

    d = tmp_path_factory.mktemp("records")
    rec = read_recording(CATALOGUE)
    plant = write_recording(d / "plant.mcap", Recording(rec.streams, [], rec.metadata))
    wrong = TABLE1.replace(X_d_prime=1.2 * TABLE1.X_d_prime)
    return record_of(d, "own", TABLE1), record_of(d, "wrong", wrong), plant


def test_the_monitor_s_verdicts_are_phid_validate_s_and_its_own_record_stays_ok(records, tmp_path) -> None:
    from phid_ros.api import validate_record
    from phid_ros.io.msg_schemas import typestore
    from phid_ros.stream import messages as m
    from phid_ros.stream.emit import emit
    from phid_ros.stream.store import EventStore

    own, _, plant = records
    store = tmp_path / "events.sqlite"
    out, pipeline = replayed(own, plant, str(store))
    check = pipeline.record_check
    assert check is not None and len(out.verdicts) == 18  # every event of the catalogue, each played in
    batch = validate_record(own, plant).result.scenarios
    assert len(batch) == len(out.verdicts)
    for v, s in zip(out.verdicts, batch, strict=True):
        # the same windows, the same function: the same numbers to the last digit
        assert [(c.channel, c.standard, c.max_error, c.band, c.passed) for c in v.checks] == [
            (c.channel, c.standard, c.max_error, c.band, c.passed) for c in s.checks
        ], (v.event_id, s.scenario)
        assert {c.channel for c in v.checks} == {"q_e", "p_e"}  # E_fd and P_m played as recorded
    assert all(v.passed for v in out.verdicts[-5:]) and check.status()[0] == OK
    assert check.drift == []  # the recalibrations find the record's machine (D in its torque form)
    kept = EventStore(store).verdicts()
    assert [k["event_id"] for k in kept] == [v.event_id for v in out.verdicts]
    assert kept[0]["checks"][0]["max_error"] == out.verdicts[0].checks[0].max_error
    # on the topic: one ModelValidation a checked event, and the record's own /diagnostics status
    types = typestore().types
    msgs = [p.message for p in emit(types, out) if p.key == "model_validation"]
    assert len(msgs) == 18 and list(msgs[0].channels) == [c.channel for c in out.verdicts[0].checks]
    assert np.array_equal(msgs[0].max_errors, [c.max_error for c in out.verdicts[0].checks])
    diag = m.diagnostics_message(types, 0, pipeline.health, None, record=check)
    [status] = [s for s in diag.status if s.name.endswith("record on file")]
    assert status.level == 0 and "passed 5 of the last 5 events" in status.message


def test_a_record_of_the_wrong_machine_is_raised_where_the_events_show_it_and_x_d_prime_drifts(records) -> None:
    _, wrong, _ = records
    out, pipeline = replayed(wrong, CATALOGUE)
    check = pipeline.record_check
    assert check is not None
    levels = [v.level for v in out.verdicts]
    failed = [i for i, v in enumerate(out.verdicts) if not v.passed]
    # the torque and voltage steps hardly show X'_d; the faults do, and the state follows them
    assert failed and all(out.verdicts[i].kind == "fault" for i in failed)
    assert levels[0] == OK
    # before any check fails, the recalibration's X'_d is already far from the record's: WARN, said
    early = [v for v in out.verdicts[: failed[0]] if v.level != OK]
    assert early and all(v.level == WARN and v.drifting[0].startswith("X'_d: record 0.6") for v in early)
    assert levels[failed[1]] in (WARN, ERROR)
    level, message = check.status()
    assert level in (WARN, ERROR) and "fault@" in message
    assert [d.name for d in check.drift] == ["X_d_prime"]
    d = check.drift[0]
    assert d.record == pytest.approx(1.2 * TABLE1.X_d_prime) and d.identified == pytest.approx(
        TABLE1.X_d_prime, rel=0.01
    )
    assert "drifting from the record: X'_d: record 0.6, identified 0.4998" in message


def _verdict(i: int, errors: dict[str, float]) -> EventVerdict:
    checks = [ChannelCheck(c, "MOD-026", e, 0.05, e <= 0.05, "machine") for c, e in errors.items()]
    return EventVerdict(f"fault@{i}", "fault", i, "GENROU", checks, [])


def test_the_record_s_state_ok_warn_error_by_its_rule() -> None:
    """OK while it passes; WARN on k of the last n events failing; ERROR beyond twice a band."""
    check = RecordCheck("GENROU", lambda s, f: None, lambda w: None, lambda p: TABLE1, RecordCheckSettings())  # type: ignore[arg-type,return-value]
    assert check.status() == (OK, "GENROU: no event checked yet")
    check.verdicts += [_verdict(0, {"q_e": 0.02}), _verdict(1, {"q_e": 0.06})]
    assert check.status()[0] == OK  # one failure of five is not yet a pattern
    check.verdicts.append(_verdict(2, {"q_e": 0.07, "p_e": 0.01}))
    level, message = check.status()
    assert level == WARN and "failed a check on 2 of the last 3 events: fault@1 (Q), fault@2 (Q)" in message
    check.verdicts.append(_verdict(3, {"q_e": 0.11}))
    level, message = check.status()
    assert level == ERROR and "Q off by 0.11 pu (2.2 x its band 0.05) at fault@3" in message
    check.verdicts += [_verdict(i, {"q_e": 0.01}) for i in range(4, 9)]
    assert check.status()[0] == OK  # the last five pass: the record is judged on what it meets now
    with pytest.raises(ValueError, match="warn_events 6 must be between 1 and window 5"):
        RecordCheckSettings(warn_events=6)


def test_drift_compares_d_in_the_record_s_torque_form() -> None:
    from phid_ros.ident.results import Estimate

    on_file = TABLE1.replace(D=P_M0)  # PSS/E's D = 0: what a D of 0.4 below P_m0 0.8 is written as
    check = RecordCheck("GENROU", lambda s, f: None, lambda w: None, lambda p: on_file, RecordCheckSettings())  # type: ignore[arg-type,return-value]
    check.p_m0 = P_M0
    est = {n: Estimate(getattr(TABLE1, n), 0.001 * getattr(TABLE1, n)) for n in PARAMETER_NAMES}
    assert check.compare(est) == []  # 0.4 written 0 and 0.4 identified: no drift
    est["X_q"] = Estimate(1.1 * TABLE1.X_q, 0.01)
    est["H"] = Estimate(TABLE1.H, math.nan)  # no std: not judged
    [d] = check.compare(est)
    assert d.name == "X_q" and d.sigmas == pytest.approx(0.1 * TABLE1.X_q / 0.01)


def test_phid_replay_with_a_record_prints_and_reports_its_verdicts(records, tmp_path, capsys) -> None:
    from phid_ros.cli.main import main

    _, wrong, _ = records
    report = tmp_path / "replay.html"
    args = ["replay", str(CATALOGUE), "--out", str(tmp_path / "o.mcap"), "--record", str(wrong)]
    assert main([*args, "--report", str(report)]) == 0
    out = capsys.readouterr().out
    assert "the record on file against each event" in out and "FAIL (Q" in out
    assert "record on file: ERROR:" in out and "drifting from the record: X'_d: record 0.6" in out
    page = report.read_text()
    assert "<h2>The record on file against each event</h2>" in page and "State at the end: <b>ERROR</b>" in page
    assert len(re.findall(r'<td class="text">fault@', page)) == 2 * 5  # Q and P of each of the five faults
    assert "Failing events, recorded against simulated" in page and page.count('src="data:image/png') == 3 + 4
    assert (
        main(["replay", str(CATALOGUE), "--out", str(tmp_path / "p.mcap"), "--record", str(tmp_path / "no.dyr")]) == 2
    )
    assert "no.dyr" in capsys.readouterr().err
