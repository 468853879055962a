"""The library's front page: the example in ``phid_ros.api``'s docstring runs as written."""

from __future__ import annotations

import doctest
import os
from pathlib import Path

import pytest

import phid_ros.api

ROOT = Path(__file__).resolve().parents[1]


def test_the_api_docstring_example_runs_and_gives_the_catalogues_inertia() -> None:
    here = Path.cwd()
    os.chdir(ROOT)  # the example reads bags/catalogue, relative as a user in a clone types it
    try:
        failed, attempted = doctest.testmod(phid_ros.api, raise_on_error=False, verbose=False)
    finally:
        os.chdir(here)
    assert attempted >= 6
    assert failed == 0


def test_export_record_writes_what_phid_export_writes(tmp_path: Path) -> None:
    """The library's export is the command's: the same record text, the same warnings' reasons."""
    from phid_ros.api import export_record
    from phid_ros.cli.main import main

    result = tmp_path / "catalogue.json"
    assert main(["identify", str(ROOT / "bags" / "catalogue"), "--json", str(result)]) == 0
    assert main(["export", str(result), "--format", "psse-dyr", "--out", str(tmp_path / "cli.dyr")]) == 0
    done = export_record(result, "psse-dyr")
    assert done.text == (tmp_path / "cli.dyr").read_text()
    assert done.record.model == "GENROU" and done.written["H"] == done.record.values["H"]
    assert done.sources["D"].endswith("(PSS/E's torque form)") and done.written["D"] != done.record.values["D"]


def test_replay_to_bag_writes_what_phid_replay_writes(tmp_path: Path) -> None:
    """The library's replay is the command's: the same output bag, byte for byte, and the pipeline
    it returns closed with what the terminal summary reads."""
    from phid_ros.api import replay_to_bag
    from phid_ros.cli.main import main

    bag = ROOT / "bags" / "catalogue"
    assert main(["replay", str(bag), "--out", str(tmp_path / "cli.mcap")]) == 0
    seen = []
    run = replay_to_bag(bag, tmp_path / "api.mcap", progress=seen.append)
    assert (tmp_path / "api.mcap").read_bytes() == (tmp_path / "cli.mcap").read_bytes()
    assert run.outputs.events and sum(run.collector.counts.values()) > 1000
    assert seen and seen[-1].played_s > 600 and seen[-1].events == len(run.outputs.events)
    assert not (tmp_path / "api.mcap.partial").exists()


def test_track_file_tracks_what_phid_track_tracks(tmp_path: Path) -> None:
    """The library's tracker is the command's: the same hops, the same output messages."""
    from phid_ros.api import track_file
    from phid_ros.cli.main import main
    from phid_ros.model.parameters import TABLE1

    bag = ROOT / "bags" / "catalogue"
    assert main(["track", str(bag), "--window", "120", "--hop", "60", "--out", str(tmp_path / "cli.mcap")]) == 0
    seen = []
    run = track_file(bag, TABLE1, 120.0, 60.0, out=tmp_path / "api.mcap", on_point=lambda p, read: seen.append(read))
    assert (tmp_path / "api.mcap").read_bytes() == (tmp_path / "cli.mcap").read_bytes()
    assert len(run.points) == len(seen) >= 5 and seen == sorted(seen) and 0 < seen[0] < seen[-1] <= 1.0
    assert run.points[0].t_ns - run.start_ns == pytest.approx(120e9, abs=1e9)


def test_import_recordings_reads_what_the_import_commands_write(tmp_path: Path) -> None:
    """The library's import is the commands': the same recording, byte for byte once written, and
    the same warnings; a CSV set's manifest read through the same face."""
    from phid_ros.api import import_recordings, write_output
    from phid_ros.cli.main import main
    from phid_ros.io.recording import DEFAULT_BLOCK_SIZE
    from test.io.field.field_sets import build_up_log

    build_up_log(tmp_path / "A.csv", 11.0, seed=0)
    (tmp_path / "map.yaml").write_text(
        "machine: {mva: 160, kv: 16, f_nominal_hz: 50}\ntime: t_s\nchannels:\n"
        "  v_t: {name: Ug_kV, unit: kV_ll}\n  v_f: {name: Uf_V, unit: V}\n  i_fd: {name: If_A, unit: A}\n"
    )
    args = [str(tmp_path / "A.csv"), "--map", str(tmp_path / "map.yaml")]
    assert main(["import-pmu", *args, "--out", str(tmp_path / "cli.mcap")]) == 0
    rec = import_recordings([tmp_path / "A.csv"], [tmp_path / "map.yaml"], kind="pmu")
    write_output(tmp_path / "api.mcap", rec, DEFAULT_BLOCK_SIZE)
    assert (tmp_path / "api.mcap").read_bytes() == (tmp_path / "cli.mcap").read_bytes()
    assert any("calibrated on the air-gap line" in w for w in rec.warnings)
    # the CSV set written back reads through the same face, its scenarios and their samples as they were
    assert main(["import-pmu", *args, "--out", str(tmp_path / "set" / "manifest.json")]) == 0
    back = import_recordings([tmp_path / "set" / "manifest.json"], kind="csv")
    assert [s.name for s in back.scenarios] == [s.name for s in rec.scenarios]
    with pytest.raises(phid_ros.api.PhidError, match="one of csv, comtrade, pmu"):
        import_recordings([tmp_path / "A.csv"], kind="xls")


def test_simulate_to_file_writes_what_phid_simulate_writes(tmp_path: Path) -> None:
    """The library's simulation is the command's: the same bag and truth, byte for byte, for the
    paper's scenarios and for an ambient run with a drift."""
    from phid_ros.api import simulate_ambient_to_file, simulate_to_file
    from phid_ros.cli.main import main
    from phid_ros.sim.ambient import AmbientSettings, Drift
    from phid_ros.sim.runner import SimulationConfig
    from phid_ros.sim.scenarios import find_scenario, with_duration
    from phid_ros.sim.sensors import SensorModel

    assert main(["simulate", "--scenario", "S04", "--duration", "3", "--out", str(tmp_path / "cli.mcap")]) == 0
    cfg = SimulationConfig(f_nominal_hz=50.0, sensors=SensorModel(seed=0))
    done = simulate_to_file([with_duration(find_scenario("S04"), 3.0)], cfg, tmp_path / "api.mcap")
    assert (tmp_path / "api.mcap").read_bytes() == (tmp_path / "cli.mcap").read_bytes()
    assert done.truth.read_bytes() == (tmp_path / "cli.mcap.truth.json").read_bytes() and done.span_s > 3.0

    drift = ["--drift", "T_d0_prime=0.1@10-50"]
    assert main(["simulate", "--ambient", "60", *drift, "--out", str(tmp_path / "cli_a.mcap")]) == 0
    settings = AmbientSettings(duration_s=60.0, drifts=(Drift("T_d0_prime", 10.0, 50.0, 0.1),), seed=0)
    ambient = simulate_ambient_to_file(settings, cfg, tmp_path / "api_a.mcap")
    assert (tmp_path / "api_a.mcap").read_bytes() == (tmp_path / "cli_a.mcap").read_bytes()
    assert ambient.truth.read_bytes() == (tmp_path / "cli_a.mcap.truth.json").read_bytes()
