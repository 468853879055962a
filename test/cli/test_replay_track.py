"""phid replay / phid track / phid simulate --ambient, end to end."""

from __future__ import annotations

from pathlib import Path

import pytest

from phid_ros.cli.main import main
from phid_ros.io.bags.recordings import topic_table
from phid_ros.stream.levels import Level

BAGS = Path(__file__).resolve().parents[2] / "bags"


def test_replay_writes_every_output_and_prints_the_summary(tmp_path, capsys):
    out = tmp_path / "out.mcap"
    assert (
        main(["replay", str(BAGS / "validation.mcap"), "--out", str(out), "--store", str(tmp_path / "e.sqlite")]) == 0
    )
    topics = {t: n for t, _, n in topic_table(out)}
    assert topics["/phid/events"] == 3 and topics["/phid/event_windows"] == 3
    assert topics["/diagnostics"] >= 59  # one per second of the 60 s recording
    text = capsys.readouterr().out
    assert "V1_power_step" in text and "V3_fault_150ms" in text and "stream health" in text
    # three validation events cannot identify anything: said, not invented
    assert "parameters in force at the end: none" in text or "rejected" in text
    assert (tmp_path / "e.sqlite").stat().st_size > 0
    assert "from earlier runs" not in text
    # the same bag again into the kept store: its events take part, and the summary says so
    assert (
        main(["replay", str(BAGS / "validation.mcap"), "--out", str(out), "--store", str(tmp_path / "e.sqlite")]) == 0
    )
    assert "e.sqlite: 3 events from earlier runs take part in the recalibrations" in capsys.readouterr().out


def test_simulate_ambient_then_track(tmp_path, capsys):
    bag = tmp_path / "drift.mcap"
    assert main(["simulate", "--ambient", "420", "--drift", "T_d0_prime=0.1@60-400", "--out", str(bag)]) == 0
    truth = (tmp_path / "drift.mcap.truth.json").read_text()
    assert '"drifts"' in truth and "T_d0_prime" in truth
    capsys.readouterr()
    out = tmp_path / "tracked.mcap"
    assert main(["track", str(bag), "--window", "300", "--hop", "60", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "3 hops" in text and "T'_d0" in text
    assert dict((t, n) for t, _, n in topic_table(out))["/phid/tracked_parameters"] == 3


def test_bad_drift_and_short_recording(tmp_path):
    import subprocess
    import sys

    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "phid_ros.cli.main",
            "simulate",
            "--ambient",
            "10",
            "--drift",
            "T_d0_prime+10%",
            "--out",
            str(tmp_path / "x.mcap"),
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2 and "expected NAME=REL@START-END" in r.stderr
    r = subprocess.run(
        [sys.executable, "-m", "phid_ros.cli.main", "track", str(BAGS / "validation.mcap")],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2 and "shorter than one tracking window" in r.stderr


def test_replay_aligns_on_the_recordings_own_rate(tmp_path, capsys):
    """A bag sampled at 100 Hz: the grid follows its PT/CT rate (it was 1 kHz whatever the data, and every
    window came out stale: nothing identified)."""
    import re
    from dataclasses import replace

    from phid_ros.io.bags.recordings import read_recording, write_recording
    from phid_ros.io.recording import Recording

    rec = read_recording(BAGS / "catalogue")
    streams = {
        n: replace(
            s,
            t_ns=s.t_ns[::10].copy(),
            channels={c: v[::10].copy() for c, v in s.channels.items()},
            period_ns=10 * s.period_ns,
            msg_seq=None,
            msg_offsets=None,
        )
        for n, s in rec.streams.items()
    }
    bag = write_recording(tmp_path / "c100.mcap", Recording(streams, rec.scenarios, rec.metadata))
    assert main(["replay", str(bag), "--out", str(tmp_path / "out.mcap")]) == 0
    text = capsys.readouterr().out
    assert "stale" not in text and "recalibration at 630.0 s with 16 event(s): adopted" in text
    h = float(re.search(r"^ H\s+s\s+([0-9.]+)\(", text, re.M).group(1))
    assert h == pytest.approx(3.48, rel=0.005)


def test_the_replay_health_log_stays_bounded_and_keeps_a_short_error() -> None:
    from phid_ros.stream.output_bag import HEALTH_LOG_MAX, OutputCollector
    from phid_ros.stream.pipeline import MonitorPipeline

    pipeline = MonitorPipeline()
    collector = OutputCollector(pipeline)
    for k in range(3 * HEALTH_LOG_MAX):  # a day of one-second snapshots, one of them ERROR
        collector._log_health(k, {"pt_ct": (Level.ERROR if k == 12_345 else Level.OK, k, 0, 0)})
    pipeline.close()
    log = collector.health_log
    assert HEALTH_LOG_MAX // 2 <= len(log) <= HEALTH_LOG_MAX
    [error] = [snap["pt_ct"] for _, snap in log if snap["pt_ct"][0] == Level.ERROR]
    assert 12_345 <= error[1] < 12_345 + 8  # its merged neighbours' later running total
    assert log[-1][1]["pt_ct"][1] == 3 * HEALTH_LOG_MAX - 1  # the running totals reach the end
    assert [t for t, _ in log] == sorted(t for t, _ in log)


def test_a_recalibration_is_said_as_what_happened_to_the_set_in_force() -> None:
    """The main job's first line of results read "rejected: ... did not run" for a pipeline waiting
    for more events; now waiting, adopted and kept read as such, withheld names as the tables write them."""
    from phid_ros.cli.replay import recalibration_text
    from phid_ros.model.parameters import TABLE1
    from phid_ros.stream.recalibration import RecalibrationOutcome

    def outcome(accepted: bool, status: str, in_force, **facts) -> str:
        made = RecalibrationOutcome(accepted, status, in_force, None, ["a"], 31 * 10**9, 0.1, **facts)
        return recalibration_text(made, 10**9)

    why = "stage 1 (H, D) did not run: too few"
    waiting = outcome(False, f"kept last good set: incomplete result ({why})", None, why=why)
    said = (
        "recalibration at 30.0 s with 1 event(s): no set yet (the events so far do not determine every parameter): "
        "stage 1 (H, D) did not run"
    )
    assert waiting == said + ": too few"
    adopted = outcome(True, "ok; poorly identified: D, X_q_prime", TABLE1, flagged=["D", "X_q_prime"])
    assert adopted.endswith("adopted (withheld as poorly identified: D, X'_q)")
    jump = "implausible jump (X_d +40 %)"
    kept = outcome(False, f"kept last good set: {jump}", TABLE1, why=jump)
    assert kept.endswith("not adopted, the set in force kept (implausible jump (X_d +40 %))")
    # a window skipped beside an adopted set: said after the flagged names, not read as one of them
    skipped = outcome(
        True, "ok; poorly identified: D; skipped: w1: too short", TABLE1, flagged=["D"], skipped=["w1: too short"]
    )
    assert skipped.endswith("adopted (withheld as poorly identified: D; skipped: w1: too short)")
