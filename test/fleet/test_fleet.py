"""Fleet recalibration on a two-worker Dask LocalCluster, with the parameter history per unit.

Six short simulated recordings of three units: U1 twice unchanged, U2 with T'_d0 drifted
+8 % on the second day, U3 once good and once corrupt.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest

from phid_ros.errors import PhidError
from phid_ros.fleet.history import History, changes
from phid_ros.fleet.inventory import discover
from phid_ros.fleet.run import FleetOptions, fleet_lock, run_fleet
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1

BAGS = Path(__file__).resolve().parents[2] / "bags"
DAY_NS = 86_400 * 10**9
DRIFT = 1.08  # U2's T'_d0 on its second day


@pytest.fixture(scope="module")
def inventory(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.sim.recording import DEFAULT_START_NS, recording_from_runs
    from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
    from phid_ros.sim.scenarios import paper_catalogue
    from phid_ros.sim.sensors import SensorModel

    root = tmp_path_factory.mktemp("fleet") / "inventory"
    catalogue = [replace(s, duration=6.0) for s in paper_catalogue()]  # the shortest windows that identify all 8
    plan = {"U1": [1.0, 1.0], "U2": [1.0, DRIFT], "U3": [1.0]}
    seed = 0
    for unit, scales in plan.items():
        (root / unit).mkdir(parents=True)
        for day, scale in enumerate(scales):
            seed += 1
            params = replace(TABLE1, T_d0_prime=TABLE1.T_d0_prime * scale)
            cfg = SimulationConfig(params=params, restore_ramp=1.0, restore_hold=1.0, sensors=SensorModel(seed=seed))
            rec = recording_from_runs(simulate_scenarios(catalogue, cfg), cfg, start_ns=DEFAULT_START_NS + day * DAY_NS)
            write_recording(root / unit / f"day{day}.mcap", rec)
    # a corrupt recording: an MCAP magic and then garbage
    (root / "U3" / "day1.mcap").write_bytes(b"\x89MCAP0\r\n" + b"not a record " * 50)
    return root


def test_six_recordings_five_rows_one_failure_drift_flagged_rerun_does_nothing_killed_worker_loses_nothing(
    inventory: Path, tmp_path: Path
):
    out = tmp_path / "fleet"
    pids: dict[str, int] = {}
    killed: list[int] = []
    client_box: list = []

    def on_cluster(client) -> None:
        client_box.append(client)
        pids.update(client.run(os.getpid))

    def on_row(row, done: int, total: int) -> None:
        if killed:
            return
        # kill a worker in the middle of a task: the scheduler must run the task again elsewhere
        client = client_box[0]
        busy = [addr for addr, tasks in client.processing().items() if tasks]
        for _ in range(50):
            if busy:
                break
            time.sleep(0.05)
            busy = [addr for addr, tasks in client.processing().items() if tasks]
        if busy:
            os.kill(pids[busy[0]], signal.SIGKILL)
            killed.append(pids[busy[0]])

    result = run_fleet(inventory, out, FleetOptions(workers=2, dashboard=False), on_cluster=on_cluster, on_row=on_row)
    assert killed, "no task was running when the test wanted to kill its worker"
    assert (result.recordings, result.submitted, result.skipped) == (6, 6, 0)

    with History(out / "history.sqlite", create=False) as h:
        rows = h.rows()
    assert len(rows) == 6
    ok = [r for r in rows if r.status == "ok"]
    failed = [r for r in rows if r.status == "failed"]
    assert len(ok) == 5 and len(failed) == 1
    assert failed[0].unit == "U3" and failed[0].recording.endswith("day1.mcap")
    assert "day1.mcap" in failed[0].error and "\n" not in failed[0].error
    for r in ok:  # every good row is a complete, well-identified set close to the truth it was simulated with
        truth = TABLE1.as_dict()
        if r.unit == "U2" and r.start_ns and r.start_ns > min(x.start_ns for x in ok if x.unit == "U2"):
            truth["T_d0_prime"] *= DRIFT
        for name in PARAMETER_NAMES:
            assert r.well_identified(name), (r.unit, name)
            tol = 0.06 if name == "D" else 0.01
            assert r.values[name] == pytest.approx(truth[name], rel=tol), (r.unit, name)
        assert r.start_ns is not None and r.end_ns > r.start_ns and r.wall_s > 0

    # a fleet row carries what phid identify finds of the recording: the exciter and governor too
    import json

    from phid_ros.cli.main import main

    assert main(["identify", ok[0].recording, "--no-baseline", "--json", str(out / "one.json")]) == 0
    cli = json.loads((out / "one.json").read_text())
    assert set(ok[0].controls) == {"exciter", "governor", "stabiliser"}
    assert json.dumps(ok[0].controls, sort_keys=True) == json.dumps(cli["controls"], sort_keys=True)

    flagged = changes(rows)
    assert [(c.unit, c.parameter) for c in flagged] == [("U2", "T_d0_prime")]
    assert flagged[0].relative == pytest.approx(DRIFT - 1, abs=0.01)

    # the rerun finds everything in the history: no cluster, no task, no new row
    started: list = []
    again = run_fleet(inventory, out, FleetOptions(workers=2, dashboard=False), on_cluster=started.append)
    assert (again.submitted, again.skipped, started) == (0, 6, [])
    with History(out / "history.sqlite", create=False) as h:
        assert len(h.rows()) == 6


def test_a_second_run_on_the_same_fleet_folder_is_refused(inventory: Path, tmp_path: Path):
    out = tmp_path / "fleet"
    out.mkdir()
    with fleet_lock(out):
        with pytest.raises(PhidError, match=r"another phid fleet run \(pid \d+\) is using this folder"):
            run_fleet(inventory, out, FleetOptions(workers=1, dashboard=False))


def test_lists_and_trees_name_the_same_recordings_and_empty_units_are_reported(inventory: Path, tmp_path: Path):
    items, warnings = discover(inventory)
    assert [(i.unit, i.path.name) for i in items] == [
        ("U1", "day0.mcap"),
        ("U1", "day1.mcap"),
        ("U2", "day0.mcap"),
        ("U2", "day1.mcap"),
        ("U3", "day0.mcap"),
        ("U3", "day1.mcap"),
    ]
    assert warnings == []
    listed = tmp_path / "fleet.yaml"
    listed.write_text("".join(f"- {{unit: {i.unit}, recording: {i.path}}}\n" for i in items))
    assert discover(listed)[0] == items
    as_map = tmp_path / "map.yml"
    as_map.write_text("U1: [" + ", ".join(str(i.path) for i in items if i.unit == "U1") + "]\n")
    assert discover(as_map)[0] == items[:2]
    table = tmp_path / "fleet.csv"
    table.write_text("unit,recording\n" + "".join(f"{i.unit},{i.path}\n" for i in items))
    assert discover(table)[0] == items
    tree = tmp_path / "tree"
    (tree / "U9").mkdir(parents=True)
    (tree / "U1" / "2026" / "01").mkdir(parents=True)
    (tree / "U1" / "2026" / "01" / "a.mcap").symlink_to(items[0].path)
    (tree / "U1" / "2026" / "01" / "a.mcap.truth.json").write_text("{}")
    (tree / "stray.mcap").symlink_to(items[0].path)
    found, notes = discover(tree)
    assert [(i.unit, i.path.name) for i in found] == [("U1", "day0.mcap")]  # resolved through the link
    assert any("unit U9: no recordings" in n for n in notes)
    assert any("stray.mcap: not inside a unit folder" in n for n in notes)


def test_bad_lists_are_one_line_errors(tmp_path: Path):
    bad = tmp_path / "bad.csv"
    bad.write_text("machine,file\nU1,a.mcap\n")
    with pytest.raises(PhidError, match=r"bad\.csv: header must name 'unit' and 'recording'"):
        discover(bad)
    (tmp_path / "empty").mkdir()
    with pytest.raises(PhidError, match=r"empty: no recordings found"):
        discover(tmp_path / "empty")


def test_a_listed_recording_that_does_not_exist_is_a_failure_row_without_a_task(tmp_path: Path):
    listed = tmp_path / "fleet.csv"
    listed.write_text("unit,recording\nU7,gone.mcap\n")
    started: list = []
    result = run_fleet(listed, tmp_path / "out", FleetOptions(workers=1, dashboard=False), on_cluster=started.append)
    assert started == [] and result.failed == 1
    assert result.rows[0].error.endswith("gone.mcap: no such file")


def _phid(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "phid_ros.cli.main", *args], capture_output=True, text=True, cwd=cwd, timeout=120
    )


def test_an_unreachable_scheduler_is_a_one_line_error_within_seconds(inventory: Path, tmp_path: Path):
    t0 = time.perf_counter()
    r = _phid("fleet", str(inventory), "--out", str(tmp_path / "f"), "--scheduler", "tcp://127.0.0.1:9")
    assert r.returncode == 2
    assert r.stderr.strip().startswith("phid: error: --scheduler tcp://127.0.0.1:9: no Dask scheduler answered")
    assert len(r.stderr.strip().splitlines()) == 1
    assert time.perf_counter() - t0 < 40


def test_history_of_an_unknown_unit_names_the_known_ones(tmp_path: Path):
    from phid_ros.fleet.history import Row

    with History(tmp_path / "history.sqlite") as h:
        h.add(Row("U1", "/r.mcap", "abc", "failed", "0", error="x"))
    r = _phid("history", "U5", "--fleet", str(tmp_path))
    assert r.returncode == 2
    assert (
        r.stderr.strip()
        == f"phid: error: {tmp_path}/history.sqlite: no recordings of unit 'U5' (units in this history: U1)"
    )
    r = _phid("history", "U5", "--fleet", str(tmp_path / "nowhere"))
    assert r.returncode == 2 and "no fleet history here" in r.stderr


def test_history_command_flags_a_jump_and_writes_its_report(tmp_path: Path, capsys: pytest.CaptureFixture):
    from phid_ros.cli.main import main
    from phid_ros.fleet.history import Row

    def row(day: int, t_d0: float, status: str = "ok") -> Row:
        r = Row("U1", f"/rec/day{day}.mcap", f"h{day}", status, "0.1.0", start_ns=day * DAY_NS, end_ns=day * DAY_NS + 1)
        for name in PARAMETER_NAMES:
            r.values[name], r.stds[name], r.identifiable[name] = getattr(TABLE1, name), 0.001, True
        r.values["T_d0_prime"] = t_d0
        return r

    with History(tmp_path / "history.sqlite") as h:
        for r in (row(1, 1.437), row(2, 1.438), row(3, 1.5807), row(4, 1.58)):  # +9.9 % on day 3: 101 σ
            h.add(r)
        h.add(Row("U1", "/rec/bad.mcap", "hx", "failed", "0.1.0", error="bad.mcap: truncated"))
    report = tmp_path / "u1.html"
    assert main(["history", "U1", "--fleet", str(tmp_path), "--report", str(report)]) == 0
    out = capsys.readouterr().out
    assert "T'_d0 changed +9.92% (100.9 σ) between 1970-01-03 00:00 and 1970-01-04 00:00" in out
    assert "1.4370(10)" in out and "1.5807(10)!" in out and "FAILED" in out and "truncated" in out
    html = report.read_text()
    assert html.count('<img src="data:image/png;base64,') == 1
    assert "T&#x27;_d0 +9.92% (100.9 σ)" in html or "T'_d0 +9.92% (100.9 σ)" in html
    assert html.count("<tr>") == 1 + 5  # header + four sets + the failure
    from test.browser import assert_readable, chromium

    if chromium() is not None:  # as a reader sees it (skip reasons: test/cli/test_reports_and_terminal.py)
        assert_readable(report, figures=1)


def test_a_csv_scenario_set_and_a_rosbag2_folder_are_one_recording_each(tmp_path: Path):
    from phid_ros.io.files.digest import content_hash

    unit = tmp_path / "tree" / "G1"
    (unit / "set").mkdir(parents=True)
    (unit / "set" / "manifest.json").write_text('{"scenarios": [{"file": "s1.csv", "kind": "fault"}]}')
    (unit / "set" / "s1.csv").write_text("t,v_t\n0,1\n")
    (unit / "set" / "result.json").write_text('{"parameters": {}}')  # a results JSON is not a recording
    (unit / "bag").mkdir()
    (unit / "bag" / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (unit / "bag" / "bag_0.mcap").write_bytes(b"x")
    (unit / "x.mcap.truth.json").write_text('{"scenarios": [{"file": "a"}]}')
    found, _ = discover(tmp_path / "tree")
    assert [i.path.relative_to(unit).as_posix() for i in found] == ["bag", "set/manifest.json"]
    before = content_hash(found[1].path)
    (unit / "set" / "s1.csv").write_text("t,v_t\n0,1.01\n")  # a CSV of the set changed: another recording
    assert content_hash(found[1].path) != before
    bag = content_hash(found[0].path)
    (unit / "bag" / "bag_0.mcap").write_bytes(b"y")
    assert content_hash(found[0].path) != bag


def test_links_are_followed_once_and_empty_or_dangling_entries_are_named(tmp_path: Path):
    """A link loop ran the same bag 81 times; a 0-byte manifest was ignored without a word; a
    dangling link printed '(nan s)'. Now each is named, and every recording is listed once."""
    root = tmp_path / "fleet"
    unit = root / "G1"
    (unit / "day1").mkdir(parents=True)
    shutil.copy(BAGS / "validation.mcap", unit / "day1" / "a.mcap")
    (unit / "day1" / "loop").symlink_to(unit, target_is_directory=True)  # G1/day1/loop -> G1
    (unit / "again.mcap").symlink_to(unit / "day1" / "a.mcap")
    (unit / "manifest.json").write_text("")
    (unit / "gone.mcap").symlink_to(tmp_path / "nowhere.mcap")
    items, warnings = discover(root)
    assert [(i.unit, i.path.name) for i in items] == [("G1", "a.mcap")]
    text = "\n".join(warnings)
    assert "(a link loop or a duplicate); skipped" in text
    assert "a.mcap: the same file as " in text and text.count("; skipped") == 4
    assert "manifest.json: empty; skipped" in text
    assert "gone.mcap: a dangling link (to " in text


def test_a_list_naming_one_recording_twice_runs_it_once(tmp_path: Path):
    shutil.copy(BAGS / "validation.mcap", tmp_path / "a.mcap")
    listed = tmp_path / "fleet.csv"
    listed.write_text("unit,recording\nU1,a.mcap\nU1,./a.mcap\nU2,a.mcap\n")
    items, warnings = discover(listed)
    assert [(i.unit, i.path.name) for i in items] == [("U1", "a.mcap"), ("U2", "a.mcap")]
    assert warnings == [f"{listed}: entry 2: ./a.mcap of U1 is entry 1 again; skipped"]


def test_a_rerun_after_the_method_changed_identifies_again_and_says_how_many(tmp_path: Path, monkeypatch):
    """The fleet used to skip a recording already in the history for this release: a change that
    moved numbers kept the old ones. It keys on the method version now."""
    from phid_ros.fleet import run as fleet_run

    root = tmp_path / "fleet"
    (root / "G1").mkdir(parents=True)
    shutil.copy(BAGS / "catalogue" / "catalogue.mcap", root / "G1" / "a.mcap")
    opts = FleetOptions(workers=1, dashboard=False)
    first = run_fleet(root, tmp_path / "out", opts)
    assert (first.submitted, first.skipped, first.redone) == (1, 0, 0)
    again = run_fleet(root, tmp_path / "out", opts)
    assert (again.submitted, again.skipped, again.redone) == (0, 1, 0)
    monkeypatch.setattr(fleet_run, "method_version", lambda: "0.2.0+changed")
    monkeypatch.setattr(fleet_run, "_check_workers", lambda client: None)  # the workers run the real code
    changed = run_fleet(root, tmp_path / "out", opts)
    assert (changed.submitted, changed.skipped, changed.redone) == (1, 0, 1)
