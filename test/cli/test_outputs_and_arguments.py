"""Outputs never overwrite an input, never stay half-written, and the README's commands re-run;
ordinary mistakes on the command line are one line, exit 2, before any work."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from phid_ros.cli.main import main

BAGS = Path(__file__).resolve().parents[2] / "bags"


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory, short_recording):
    from phid_ros.io.bags.recordings import write_recording

    return write_recording(tmp_path_factory.mktemp("bag") / "short.mcap", short_recording)


def test_identify_refuses_to_write_over_its_own_truth_file(tmp_path, capsys):
    truth = tmp_path / "truth.json"
    truth.write_text((BAGS / "catalogue.truth.json").read_text())
    before = truth.read_bytes()
    assert main(["identify", str(BAGS / "catalogue"), "--truth", str(truth), "--json", str(truth)]) == 2
    assert "is an input of this command" in capsys.readouterr().err and truth.read_bytes() == before


def test_diagnose_refuses_a_report_over_the_manifest(tmp_path, capsys):
    manifest = tmp_path / "manifest.json"
    manifest.write_text("{}")
    assert main(["diagnose", str(manifest), "--report", str(manifest)]) == 2
    assert "is an input of this command" in capsys.readouterr().err and manifest.read_text() == "{}"


def test_an_output_over_a_csv_the_manifest_names_is_refused(tmp_path, capsys):
    """The manifest's own files are inputs too: ``--json set/s1.csv`` replaced a scenario."""
    (tmp_path / "s1.csv").write_text("t,v_t\n")
    manifest = tmp_path / "manifest.json"
    manifest.write_text(json.dumps({"scenarios": [{"file": "s1.csv"}]}))
    assert main(["identify", str(manifest), "--json", str(tmp_path / "s1.csv")]) == 2
    assert "s1.csv: is an input of this command" in capsys.readouterr().err
    assert (tmp_path / "s1.csv").read_text() == "t,v_t\n"


def test_the_readme_main_job_runs_twice(tmp_path, small_bag, capsys):
    out = tmp_path / "replay_out.mcap"
    assert main(["replay", str(small_bag), "--out", str(out)]) == 0
    first = out.stat().st_size
    assert main(["replay", str(small_bag), "--out", str(out)]) == 0  # its own output: replaced
    assert out.stat().st_size == first and not (tmp_path / "replay_out.partial.mcap").exists()


def test_replay_does_not_overwrite_a_file_it_did_not_write(tmp_path, small_bag, capsys):
    out = tmp_path / "precious.mcap"
    out.write_bytes(b"someone else's data")
    assert main(["replay", str(small_bag), "--out", str(out)]) == 2
    assert "not written by phid replay" in capsys.readouterr().err and out.read_bytes() == b"someone else's data"
    assert main(["replay", str(small_bag), "--out", str(out), "--force"]) == 0


def test_replay_killed_leaves_a_readable_partial_output(tmp_path):
    out = tmp_path / "o.mcap"
    cmd = [
        sys.executable,
        "-m",
        "phid_ros.cli.main",
        "replay",
        str(BAGS / "catalogue"),
        "--out",
        str(out),
        "--rate",
        "60",
    ]
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    partial = tmp_path / "o.partial.mcap"
    deadline = time.time() + 60
    while time.time() < deadline and (not partial.exists() or partial.stat().st_size < 200_000):
        time.sleep(0.2)
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert not out.exists() and partial.exists()
    from phid_ros.io.bags.recordings import walked_topic_table

    topics, warnings = walked_topic_table(partial)
    counts = dict((t, n) for t, _, n in topics)
    assert counts.get("/diagnostics", 0) > 10 and counts.get("/phid/events", 0) >= 1
    assert warnings and "truncated file" in warnings[0]


def test_simulate_is_atomic_and_needs_force_to_replace(tmp_path, capsys):
    out = tmp_path / "s.mcap"
    args = ["simulate", "--scenario", "S04", "--duration", "3", "--out", str(out)]
    assert main(args) == 0
    assert out.exists() and (tmp_path / "s.mcap.truth.json").exists()
    assert not (tmp_path / "s.partial.mcap").exists()
    assert main(args) == 2 and "--force" in capsys.readouterr().err
    assert main([*args, "--force"]) == 0


@pytest.mark.parametrize(
    "argv, says",
    [
        (["track", "B", "--window", "0"], "--window: 0 must be greater than 0"),
        (["track", "B", "--hop", "0"], "--hop: 0 must be greater than 0"),
        (["track", "B", "--hop", "400"], "longer than --window"),
        (["track", "B", "--base", "missing.json"], "missing.json: no such file"),
        (["simulate", "--out", "x.mcap", "--block-size", "0"], "--block-size: 0 must be at least 1"),
        (["simulate", "--out", "x.mcap", "--ambient", "-5"], "--ambient: -5 must be greater than 0"),
        (["simulate", "--out", "x.mcap", "--ambient", "0"], "--ambient: 0 must be greater than 0"),
        (["replay", "B", "--out", "o.mcap", "--rate", "0"], "--rate: 0 must be greater than 0"),
        (["replay", "B", "--out", "o.mcap", "--rate", "-1"], "--rate: -1 must be greater than 0"),
        (["replay", "B", "--out", "/nonexistent/dir/x.mcap"], "/nonexistent/dir does not exist"),
        (["identify", "B", "--paper-maxiter", "0"], "--paper-maxiter: 0 must be at least 1"),
    ],
)
def test_ordinary_mistakes_are_one_line_exit_2_before_work(tmp_path, capsys, monkeypatch, argv, says):
    monkeypatch.chdir(tmp_path)
    argv = [str(BAGS / "catalogue") if a == "B" else a for a in argv]
    t0 = time.perf_counter()
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse refuses at parse time
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert says in err and err.startswith("phid: error:") and err.count("\n") == 1
    assert time.perf_counter() - t0 < 5  # refused before reading the recording


def test_marker_names_with_markup_characters_print_as_they_are(tmp_path, short_recording, capsys):
    import dataclasses

    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.io.recording import Recording

    named = [dataclasses.replace(s, name=f"[bold]{s.name}[/]") for s in short_recording.scenarios]
    bag = write_recording(tmp_path / "m.mcap", Recording(short_recording.streams, named, short_recording.metadata))
    assert main(["info", str(bag)]) == 0
    assert "[bold]S04" in capsys.readouterr().out
    assert main(["replay", str(bag), "--out", str(tmp_path / "o.mcap")]) == 0
    assert "[bold]S04" in capsys.readouterr().out


def test_warnings_go_to_stderr(tmp_path, small_bag, capsys):
    out = tmp_path / "r.json"
    assert main(["identify", str(small_bag), "--json", str(out), "--no-baseline"]) == 0
    cap = capsys.readouterr()
    assert "phid: warning:" in cap.err and "phid: warning:" not in cap.out and "note:" not in cap.out
    assert json.loads(out.read_text())["parameters"]["H"] is not None


def test_a_bag_folder_output_names_its_storage_after_the_folder(tmp_path):
    # built in x.partial/ and renamed at the end: the storage file inside must not keep the
    # staging name (a shipped bag read "saturation.partial.mcap", as if it were cut short)
    from phid_ros.io.bags.recordings import read_recording

    out = tmp_path / "run"
    assert main(["simulate", "--scenario", "S04", "--duration", "3", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["metadata.yaml", "run.mcap"]
    assert "partial" not in (out / "metadata.yaml").read_text()
    rec = read_recording(out)
    assert len(rec.scenarios) == 1 and not rec.warnings


def test_an_unknown_option_names_its_command_once(capsys):
    """``phid simulate --format csv`` said "phid: error: phid: unrecognized arguments" and pointed
    to the top level's help."""
    with pytest.raises(SystemExit) as stop:
        main(["simulate", "--format", "csv", "--out", "x.mcap"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err == "phid: error: simulate: unrecognized arguments: --format csv (see phid simulate --help)"


def test_info_reads_a_csv_scenario_set(tmp_path, short_recording, capsys):
    """``phid info`` on a CSV set's manifest raised "InvalidMagic: not a valid MCAP file"."""
    from phid_ros.io.csvset.csv_export import write_csv_set

    manifest = write_csv_set(tmp_path / "set", short_recording)
    assert main(["info", str(manifest)]) == 0
    out = capsys.readouterr().out
    assert f"(a CSV scenario set, {len(short_recording.scenarios)} scenarios)" in out
    assert all(sc.name in out for sc in short_recording.scenarios) and "pt_ct" in out


def test_a_bad_fix_is_said_before_the_recording_is_read(tmp_path, capsys, monkeypatch):
    """A typo in --fix was said only after the whole recording had been read and cut (2-3 s)."""
    from phid_ros.cli import identify

    read = []
    monkeypatch.setattr(identify, "cut_unit", lambda *a, **k: read.append(a))
    assert main(["identify", str(BAGS / "catalogue"), "--fix", "X_d=abc"]) == 2
    assert "--fix X_d: 'abc' is not a number" in capsys.readouterr().err and not read


def test_a_warning_folds_between_words_on_a_terminal_and_stays_one_line_in_a_pipe(monkeypatch, capsys) -> None:
    import io

    from phid_ros.cli.common import warn

    long = "the field base is off by +168.3 % " * 6
    warn(long)
    assert capsys.readouterr().err.count("\n") == 1  # piped: one line

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    tty = Tty()
    monkeypatch.setattr("sys.stderr", tty)
    monkeypatch.setattr("shutil.get_terminal_size", lambda fallback=(80, 24): __import__("os").terminal_size((60, 24)))
    warn(long)
    lines = tty.getvalue().splitlines()
    assert len(lines) > 2 and all(len(line) <= 60 for line in lines)
    assert all(line.startswith("    ") for line in lines[1:])
    assert " ".join(line.strip() for line in lines) == f"phid: warning: {long}".strip()
