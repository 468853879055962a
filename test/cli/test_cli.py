"""The phid command end to end; user errors are one line, exit status 2, no traceback."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from phid_ros.cli.main import main
from phid_ros.io.bags.recordings import read_recording
from phid_ros.model.parameters import TABLE1


def run_phid(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "phid_ros.cli.main", *args], capture_output=True, text=True)


def test_simulate_one_scenario_then_info(tmp_path, capsys):
    out = tmp_path / "s13.mcap"
    assert main(["simulate", "--scenario", "S13", "--duration", "3", "--out", str(out)]) == 0
    rec = read_recording(out)
    assert [s.name for s in rec.scenarios] == ["S13_fault_100ms"]
    assert len(rec.streams["pt_ct"]) == 13_000  # 3 s window + 10 s restore at 1 kHz
    truth = json.loads((tmp_path / "s13.mcap.truth.json").read_text())
    assert truth["parameters"] == TABLE1.as_dict()
    v = rec.streams["pt_ct"].channels["v_t"]
    assert v[1000:1100].max() < 0.3 * v[:1000].mean()
    capsys.readouterr()
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    from phid_ros.io.recording import DEFAULT_BLOCK_SIZE

    messages = -(-13_000 // DEFAULT_BLOCK_SIZE)
    assert "/generator/pt_ct" in text and f"│ {messages:>8} │" in text and "S13_fault_100ms" in text


def test_simulation_is_deterministic(tmp_path):
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    for p in (a, b):
        assert main(["simulate", "--scenario", "V1", "--duration", "2", "--seed", "4", "--out", str(p)]) == 0
    ra, rb = read_recording(a), read_recording(b)
    assert np.array_equal(ra.streams["encoder"].channels["omega"], rb.streams["encoder"].channels["omega"])


def test_import_csv_command(tmp_path, short_runs):
    from test.io.csvset.test_csv_import import write_set

    manifest = write_set(tmp_path, short_runs[:2], extra={"comment": 1.0})
    out = tmp_path / "imported"
    r = run_phid("import-csv", str(manifest), "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "phid: warning:" in r.stderr and "ignored extra column(s) ['comment']" in r.stderr  # not on stdout
    assert len(read_recording(out).scenarios) == 2


def test_simulate_to_a_csv_set_then_import_it(tmp_path, capsys):
    manifest = tmp_path / "set" / "manifest.json"
    args = ["simulate", "--scenario", "S04", "--scenario", "V1", "--duration", "2", "--out", str(manifest)]
    assert main(args) == 0
    assert sorted(p.name for p in manifest.parent.iterdir()) == [
        "S04_torque_+0.10.csv",
        "V1_power_step.csv",
        "manifest.json",
        "truth.json",
    ]
    assert main(args) == 2 and "already exists" in capsys.readouterr().err  # not replaced without --force
    out = tmp_path / "imported"
    assert main(["import-csv", str(manifest), "--out", str(out)]) == 0
    rec = read_recording(out)
    assert [s.name for s in rec.scenarios] == ["S04_torque_+0.10", "V1_power_step"]
    assert len(rec.streams["pt_ct"].t_ns) == 2 * 2000


@pytest.mark.parametrize(
    "make, args, message",
    [
        (None, ["info", "{tmp}/missing"], "phid: error: {tmp}/missing: no such bag or MCAP file"),
        ("truncated", ["info", "{tmp}/t.mcap"], "phid: error: {tmp}/t.mcap:"),
        (
            "badcol",
            ["import-csv", "{tmp}/manifest.json", "--out", "{tmp}/o"],
            "phid: error: {tmp}/s0.csv: missing column(s) 'v_t'",
        ),
        (None, ["simulate", "--scenario", "S99", "--out", "{tmp}/x"], "phid: error: unknown scenario 'S99'"),
    ],
)
def test_user_errors_are_one_line_without_traceback(tmp_path, short_runs, short_recording, make, args, message):
    if make == "truncated":
        from phid_ros.io.bags.recordings import write_recording

        p = write_recording(tmp_path / "t.mcap", short_recording)
        p.write_bytes(p.read_bytes()[:5000])
    elif make == "badcol":
        from test.io.csvset.test_csv_import import write_set

        write_set(tmp_path, short_runs[:1], mutate=lambda k, lines: [lines[0].replace("v_t", "vt")] + lines[1:])
    r = run_phid(*[a.format(tmp=tmp_path) for a in args])
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    assert lines[0].startswith(message.format(tmp=tmp_path))


def test_replay_reads_a_csv_set(tmp_path):
    """Every form an import or a simulation writes is read by every command: replay refused a CSV set."""
    manifest = tmp_path / "set" / "manifest.json"
    assert main(["simulate", "--scenario", "S04", "--duration", "4", "--out", str(manifest)]) == 0
    out = tmp_path / "replay.mcap"
    assert main(["replay", str(manifest), "--out", str(out)]) == 0
    assert out.stat().st_size > 0


def test_simulate_starts_the_recording_where_start_says(tmp_path, capsys):
    """Recordings of one unit on different days (phid fleet, phid history) need their own dates."""
    from phid_ros.io.bags.recordings import read_recording
    from phid_ros.model.conventions import stamp_of_utc, utc_of_stamp

    out = tmp_path / "s04.mcap"
    assert (
        main(["simulate", "--scenario", "S04", "--duration", "2", "--start", "2026-03-01T08:30:00Z", "--out", str(out)])
        == 0
    )
    start = read_recording(out).span_ns()[0]
    assert utc_of_stamp(start).isoformat() == "2026-03-01T08:30:00+00:00"
    assert stamp_of_utc("2026-03-01") == stamp_of_utc("2026-03-01T00:00:00+00:00") == 1_772_323_200 * 10**9
    capsys.readouterr()
    with pytest.raises(SystemExit) as stop:  # refused as the arguments are read
        main(["simulate", "--scenario", "S04", "--start", "yesterday", "--out", str(tmp_path / "x.mcap")])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "'yesterday' is not an ISO 8601 date-time" in err and not (tmp_path / "x.mcap").exists()


def test_the_help_compiles_nothing_and_imports_no_numba() -> None:
    """``phid --help`` and a command's help import neither numba nor scipy (over a second of a
    start-up that compiles nothing); the control models' loops compile on their first call."""
    import subprocess
    import sys

    code = (
        "import sys\nfrom phid_ros.cli.main import main\n"
        "for args in (['--help'], ['identify', '--help'], ['simulate', '--help']):\n"
        "    try:\n        main(args)\n    except SystemExit:\n        pass\n"
        "print(sorted(m for m in ('numba', 'scipy') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"
