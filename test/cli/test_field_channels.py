"""A commissioning day's trend logs through the command line: import, info, identify, export."""

from __future__ import annotations

import json
import re

import pytest

from phid_ros.cli.main import main
from phid_ros.model.parameters import TABLE1
from phid_ros.stream.levels import Level
from test.io.field.field_sets import FIELD_BASE_A, FIELD_BASE_V, trend_log_set


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("commissioning")
    paths, cmap = trend_log_set(d, TABLE1)
    stated = d / "stated.yaml"
    stated.write_text(cmap.read_text().replace("{name: UF, unit: V}", f"{{name: UF, unit: V, base: {FIELD_BASE_V}}}"))
    stated.write_text(stated.read_text().replace("  i_fd: {name: IF, unit: A}\n", ""))
    return d, paths, cmap, stated


def test_import_info_identify_export(folder, capsys) -> None:
    d, paths, cmap, _ = folder
    bag = d / "all.mcap"
    assert main(["import-pmu", *map(str, paths), "--map", str(cmap), "--out", str(bag)]) == 0
    err = capsys.readouterr().err
    assert "v_f (UF): 1 pu = 123." in err and "resampled onto 208 per s" in err
    assert main(["info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "what these channels determine (not recorded: theta_t, i_d, i_q, omega, delta, p_m)" in out
    assert "needs omega" in out
    result = d / "result.json"
    assert main(["identify", str(bag), "--fix", f"X_q={TABLE1.X_q}", "--json", str(result)]) == 0
    out = capsys.readouterr().out
    assert out.index("what these channels determine") < out.index("identified parameters")
    doc = json.loads(result.read_text())
    assert doc["parameters"]["H"] is None and doc["identifiable"]["H"] is False
    assert doc["parameters"]["T_d0_prime"] == pytest.approx(TABLE1.T_d0_prime, rel=0.01)
    assert doc["determined_by"]["T_d0_prime"].startswith("no-load field steps")
    # with the field current recorded, X_d and X'_d by the field circuit on line (T'_d0 from no load)
    for name in ("X_d", "X_d_prime"):
        assert doc["determined_by"][name].startswith("the field circuit on line"), name
        assert doc["identifiable"][name] is True
    assert doc["parameters"]["X_d"] == pytest.approx(TABLE1.X_d, rel=0.01)
    assert doc["parameters"]["X_d_prime"] == pytest.approx(TABLE1.X_d_prime, rel=0.03)
    # the field winding's resistance from the plateaus, in ohms through the calibrated bases: the
    # look-alike's U_f per I_f at every steady state is its bases' ratio
    r_f = doc["stages"]["field_resistance"]
    assert r_f["unit"] == "ohm" and len(r_f["files"]) == 7
    assert r_f["value"] == pytest.approx(FIELD_BASE_V / FIELD_BASE_A, rel=0.005)
    said = re.search(r"field winding's resistance at the plateaus: ([0-9.]+) Ω over 7 test file", out)
    assert said and float(said[1]) == pytest.approx(FIELD_BASE_V / FIELD_BASE_A, rel=0.005)
    # a planning record needs all eight: refused, naming the first that is missing and the way on
    assert main(["export", str(result), "--format", "psse-dyr", "--out", str(d / "unit.dyr")]) == 2
    err = capsys.readouterr().err
    assert "parameter H was not determined from the recording's channels (null)" in err and "--fix H=" in err
    # the diagnosis plays the model in against every channel: refused, by name
    assert main(["diagnose", str(bag), "--workers", "1"]) == 2
    assert "not recorded: delta, i_d, i_q, omega, p_m; the diagnosis plays" in capsys.readouterr().err


def test_two_days_two_imports_one_identification(folder, capsys) -> None:
    d, paths, cmap, stated = folder
    day1, day2 = d / "day1.mcap", d / "day2.mcap"
    assert main(["import-pmu", str(paths[0]), "--map", str(cmap), "--out", str(day1)]) == 0
    assert main(["import-pmu", *map(str, paths[1:]), "--map", str(stated), "--out", str(day2)]) == 0
    capsys.readouterr()
    result = d / "both.json"
    assert main(["identify", str(day1), str(day2), "--fix", f"X_q={TABLE1.X_q}", "--json", str(result)]) == 0
    doc = json.loads(result.read_text())
    assert doc["input"] == f"{day1} + {day2}" and len(doc["input_sha256"]) == 64
    assert [e["name"] for e in doc["events"]][:2] == ["day1/noload", "day2/step_0"]
    assert doc["parameters"]["X_d_prime"] == pytest.approx(TABLE1.X_d_prime, rel=0.03)


@pytest.fixture(scope="module")
def trend_bag(folder):
    d, paths, cmap, _ = folder
    bag = d / "hostile.mcap"
    assert main(["import-pmu", *map(str, paths), "--map", str(cmap), "--out", str(bag)]) == 0
    return bag


def test_a_recording_given_twice_counts_once(folder, trend_bag, capsys) -> None:
    """``phid identify A A`` (or a copy under another name) counted as twice the data: D went from
    withheld to identified and every std shrank by √2. Now the second is left out, by name."""
    d = folder[0]
    copy = d / "copy.mcap"
    copy.write_bytes(trend_bag.read_bytes())
    once, twice = d / "once.json", d / "twice.json"
    assert main(["identify", str(trend_bag), "--fix", f"X_q={TABLE1.X_q}", "--json", str(once)]) == 0
    capsys.readouterr()
    assert main(["identify", str(trend_bag), str(copy), "--fix", f"X_q={TABLE1.X_q}", "--json", str(twice)]) == 0
    assert f"{copy}: the same recording as {trend_bag} (same content); counted once" in capsys.readouterr().err
    a, b = json.loads(once.read_text()), json.loads(twice.read_text())
    assert b["uncertainty"] == a["uncertainty"] and b["identifiable"] == a["identifiable"]


def test_an_estimate_outside_the_users_bounds_is_not_published_as_identified(folder, trend_bag) -> None:
    d = folder[0]
    out = d / "bounded.json"
    args = ["identify", str(trend_bag), "--fix", f"X_q={TABLE1.X_q}", "--bounds", "X_d=2.6:3.0", "--json", str(out)]
    assert main(args) == 0
    doc = json.loads(out.read_text())
    assert doc["parameters"]["X_d"] is None and doc["identifiable"]["X_d"] is False  # the contract: null
    withheld = doc["withheld"]["X_d"]  # what the data say, below 2.6, kept apart with its reason
    assert withheld["value"] == pytest.approx(TABLE1.X_d, rel=0.01) and "outside the bounds" in withheld["why"]
    assert "lies outside the bounds 2.6:3 (--bounds)" in " ".join(doc["problems"])
    assert main(["identify", str(trend_bag), "--fix", "X_q=2.41", "--fix", "X_q=1.0"]) == 2


def test_datasheet_values_held_beside_a_trend_log_keep_what_it_determines(folder, trend_bag, capsys) -> None:
    """Holding H, D and the q axis from a datasheet made the internal validation play in NaN
    channels (no rotor angle, speed or P_m), count that as a MOD-026 failure on every event and
    withdraw X_d, X'_d, T'_d0 that were determined. Now those events are not played in, said so."""
    d = folder[0]
    out = d / "held.json"
    t = TABLE1
    held = [f"--fix={n}={getattr(t, n)}" for n in ("X_q", "H", "D", "X_q_prime", "T_q0_prime")]
    assert main(["identify", str(trend_bag), *held, "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert all(doc["identifiable"].values()), doc["identifiable"]
    assert doc["parameters"]["X_d"] == pytest.approx(t.X_d, rel=0.01)
    assert "not played in: not recorded: delta, omega, p_m" in capsys.readouterr().err


def test_a_csv_set_import_reads_back_and_never_replaces_a_recorders_file(folder, capsys) -> None:
    """``import-pmu --out DIR/manifest.json`` into the recordings' own folder overwrote the raw
    STEM.csv with phid's converted one (exit 0); and phid's own CSV set of a trend log was refused
    by identify ("column 'i_d' is nan"). Now the first is refused before anything is written and
    the second reads back."""
    d, paths, cmap, _ = folder
    raw = {p: p.read_bytes() for p in paths}
    assert main(["import-pmu", *map(str, paths), "--map", str(cmap), "--out", str(d / "manifest.json")]) == 2
    assert "already exists; a CSV set is never written over a file" in capsys.readouterr().err
    assert all(p.read_bytes() == b for p, b in raw.items()) and not (d / "manifest.json").exists()
    manifest = d / "set" / "manifest.json"
    assert main(["import-pmu", *map(str, paths), "--map", str(cmap), "--out", str(manifest)]) == 0
    out = d / "from_csv.json"
    assert main(["identify", str(manifest), "--fix", f"X_q={TABLE1.X_q}", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["parameters"]["T_d0_prime"] == pytest.approx(TABLE1.T_d0_prime, rel=0.01)
    # the field bases travel in the manifest: the resistance is still said in ohms
    assert json.loads(manifest.read_text())["field_bases"].startswith("v_f=123.")
    r_f = doc["stages"]["field_resistance"]
    assert r_f["unit"] == "ohm" and r_f["value"] == pytest.approx(FIELD_BASE_V / FIELD_BASE_A, rel=0.005)


def test_recordings_on_different_bases_are_refused_by_name(folder, trend_bag, capsys) -> None:
    d, paths, _, stated = folder
    other = d / "other_base.yaml"
    other.write_text(stated.read_text().replace("mva: 1000", "mva: 500"))
    half = d / "half.mcap"
    assert main(["import-pmu", str(paths[1]), "--map", str(other), "--out", str(half)]) == 0
    capsys.readouterr()
    assert main(["identify", str(trend_bag), str(half), "--fix", f"X_q={TABLE1.X_q}"]) == 2
    err = capsys.readouterr().err
    assert "per unit on different bases" in err and "1000 MVA" in err and "500 MVA" in err


def test_a_bag_folder_and_its_own_mcap_count_once(folder, trend_bag, capsys) -> None:
    """Not the same bytes (the folder has its metadata.yaml), the same windows: each counted once."""
    d, paths, cmap, _ = folder
    bag = d / "bagdir"
    assert main(["import-pmu", *map(str, paths), "--map", str(cmap), "--out", str(bag)]) == 0
    [inner] = list(bag.glob("*.mcap"))
    once, both = d / "dir_once.json", d / "dir_both.json"
    assert main(["identify", str(bag), "--fix", f"X_q={TABLE1.X_q}", "--json", str(once)]) == 0
    capsys.readouterr()
    assert main(["identify", str(bag), str(inner), "--fix", f"X_q={TABLE1.X_q}", "--json", str(both)]) == 0
    a, b = json.loads(once.read_text()), json.loads(both.read_text())
    assert b["uncertainty"] == a["uncertainty"] and b["identifiable"] == a["identifiable"]
    assert f"{inner}: skipped scenario bagdir/noload: the same data as scenario bagdir/noload" in b["problems"]


def test_the_monitor_on_a_trend_log_publishes_what_the_channels_determine(folder, trend_bag, tmp_path, capsys) -> None:
    """No rotor channels, no set of eight: the recalibration publishes the parameters its events
    determine (T'_d0 from the no-load step at once; X_d with the on-line steps), the rest withheld by name."""
    from rosbags.highlevel import AnyReader

    from phid_ros.io.msg_schemas import typestore

    out = tmp_path / "monitor.mcap"
    assert main(["replay", str(trend_bag), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "recalibration at 15.0 s with 1 event(s): partial set published: T'_d0 (withheld H, D, X_d, X_q," in text
    assert "no full set in force at the end; the partial set published at" in text
    with AnyReader([out], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == "/phid/parameters"]
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    assert len(msgs) == 2 and all(m.status.startswith("partial set: withheld H, D") for m in msgs)
    assert list(msgs[0].names) == ["T_d0_prime"]
    for m in msgs:
        assert "H" not in m.names and "X_q" not in m.names and all(m.identifiable)
        for name, value, std in zip(m.names, m.values, m.std_dev):
            truth = getattr(TABLE1, name)
            assert abs(value - truth) < max(3 * std, 0.01 * truth), (name, value, std)


def test_a_test_file_from_another_machine_never_leaves_a_wrong_x_d_as_identified(folder, tmp_path) -> None:
    """One on-line test file recorded on another machine (X_d 3.0 for 2.54): X_d is either withheld
    or given with a std that covers the day's machine (measured: 2.619 +- 0.052, the odd file's
    scatter in its std; with that file left out in turn it moves to 2.54, within two stds). Each
    file of the day is left out in turn; T'_d0, from the no-load test, stays identified."""
    d, paths, cmap, _ = folder
    (tmp_path / "other").mkdir()
    other, _ = trend_log_set(tmp_path / "other", TABLE1.replace(X_d=3.0))
    odd = next(p for p in other if p.stem == "step_0")
    mixed = [p for p in paths if p.stem != "step_0"] + [odd]
    bag = tmp_path / "mixed.mcap"
    assert main(["import-pmu", *map(str, mixed), "--map", str(cmap), "--out", str(bag)]) == 0
    result = tmp_path / "r.json"
    assert main(["identify", str(bag), "--fix", f"X_q={TABLE1.X_q}", "--json", str(result)]) == 0
    doc = json.loads(result.read_text())
    x_d, std = doc["parameters"]["X_d"], doc["uncertainty"]["X_d"]
    assert not doc["identifiable"]["X_d"] or abs(x_d - TABLE1.X_d) <= 2 * std, (x_d, std)
    assert doc["identifiable"]["T_d0_prime"] and doc["parameters"]["T_d0_prime"] == pytest.approx(1.437, rel=0.01)


def test_the_monitor_holds_the_datasheet_values_it_is_given(trend_bag, tmp_path, capsys) -> None:
    """A recorder without the rotor angle: with X_q held (phid replay --fix, the node's ``held``
    parameter), the recalibration reconstructs the angle and publishes X'_d beside X_d and T'_d0."""
    from rosbags.highlevel import AnyReader

    from phid_ros.io.msg_schemas import typestore

    out = tmp_path / "held.mcap"
    assert main(["replay", str(trend_bag), "--out", str(out), "--fix", f"X_q={TABLE1.X_q}"]) == 0
    said = capsys.readouterr().out
    assert "partial set published: X_d, X'_d, T'_d0 (withheld H, D, X'_q, T'_q0: not determined" in said
    assert "; held: X_q = 2.41)" in said
    with AnyReader([out], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == "/phid/parameters"]
        last = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)][-1]
    assert list(last.names) == ["X_d", "X_d_prime", "T_d0_prime"]
    for name, value, std in zip(last.names, last.values, last.std_dev):
        truth = getattr(TABLE1, name)
        assert abs(value - truth) < max(3 * std, 0.02 * truth), (name, value, std)
    # a typo is said before the reading, in one line
    assert main(["replay", str(trend_bag), "--out", str(tmp_path / "x.mcap"), "--saturation", "0.4,0.1"]) == 2
    assert "needs S(1.2) > S(1.0) > 0" in capsys.readouterr().err


def test_the_monitor_on_a_trend_log_publishes_what_identify_finds(folder, trend_bag) -> None:
    """A recorder at 208 reports/s with jitter and without the rotor's channels, its field current
    on a stream of its own: the online pipeline carries I_fd with each window, a field step's window
    reaches back to where its test's file began, and the recalibration's partial set equals phid
    identify's on the same bag within 1 %; every declared stream is healthy (the pauses between the
    files are between marked tests)."""
    from phid_ros.api import load_recording
    from phid_ros.ident.constraints import parse_constraints
    from phid_ros.ident.pipeline import IdentifyOptions
    from phid_ros.io.recording import not_recorded
    from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings
    from phid_ros.stream.replay import replay

    d = folder[0]
    rec = load_recording(trend_bag)
    held = parse_constraints([f"X_q={TABLE1.X_q}"])
    pipeline = MonitorPipeline(
        PipelineSettings(
            period_ns=rec.streams["pt_ct"].period_ns,
            not_recorded=not_recorded(rec.metadata),
            identify=IdentifyOptions(baseline=False, constraints=held),
        )
    )
    try:
        out = replay(rec, pipeline)
        health = {n: pipeline.status(n) for n in pipeline.health}
    finally:
        pipeline.close()
    assert {n: level for n, (level, _) in health.items()} == dict.fromkeys(
        ("pt_ct", "encoder", "pmu", "excitation", "field_controller"), Level.OK
    ), health
    assert "paused 6 time(s) between marked tests" in health["pt_ct"][1]
    starts = {m.name: m.start_ns for m in rec.scenarios}
    steps = [w for w in out.windows if w.event.kind == "field_step"]
    assert len(steps) == 5 and all(w.usable and "i_fd" in w.recorded for w in steps)
    for w in steps:  # the window begins where its file does, within a report
        assert abs(int(w.t_ns[0]) - starts[w.event.name]) <= w.period_ns, w.event.name
    result = d / "monitor_identify.json"
    assert main(["identify", str(trend_bag), "--fix", f"X_q={TABLE1.X_q}", "--json", str(result)]) == 0
    doc = json.loads(result.read_text())
    partial = out.recalibrations[-1].determined
    assert set(partial) == {"X_d", "X_d_prime", "T_d0_prime"}
    for name, e in partial.items():
        assert e.value == pytest.approx(doc["parameters"][name], rel=0.01), name
    assert out.recalibrations[-1].controls["exciter"]  # fitted beside the machine, or said why not


def test_the_identify_report_of_a_recorder_s_day_draws_what_was_recorded(folder, trend_bag, monkeypatch) -> None:
    """A trend log has no speed, no I_d, I_q: the report drew them as empty axes, titled an empty
    table "Validation against the —" and footnoted its absent columns. Now the scenario figure
    holds the recorded channels alone (the rest named in its title), and the validation says why
    it did not run."""
    from phid_ros.cli import report

    drawn = []
    real = report.png_data_uri
    monkeypatch.setattr(report, "png_data_uri", lambda fig: drawn.append(fig) or real(fig))
    out = folder[0] / "day.html"
    assert main(["identify", str(trend_bag), "--report", str(out)]) == 0
    page = out.read_text()
    assert "Validation against the —" not in page and "<h2>Validation</h2><p>Not run: validation skipped" in page
    scenario_figure = next(f for f in drawn if "Identification scenarios" in f._suptitle.get_text())
    labels = {ax.get_ylabel() for ax in scenario_figure.axes if ax.get_ylabel()}
    assert labels == {"V_t (pu)", "P_e (pu)", "Q_e (pu)"}
    assert "not recorded, not drawn: Δω, I_d, I_q" in scenario_figure._suptitle.get_text()


def test_the_field_resistance_follows_each_file_and_says_its_unit(folder, tmp_path) -> None:
    """R_f from the plateaus, file by file: a winding 8 % warmer in one test (its U_f read 8 % up
    for the same I_f) reads 8 % more there and nowhere else; recorded through a map that states
    other bases (the controller's), the figure in ohms is the same; with the field in per unit it
    is said in the recorder's per unit."""
    from phid_ros.api import cut_unit, field_resistance_of, import_recordings
    from phid_ros.io.bags.recordings import write_recording

    d, paths, cmap, _ = folder
    warm = tmp_path / "step_1.csv"
    lines = paths[2].read_text().splitlines()
    head = lines[0].split(";")
    k = head.index("UF")

    def warmer(row: str) -> str:
        cells = row.split(";")
        cells[k] = f"{1.08 * float(cells[k].replace(',', '.')):.6f}".replace(".", ",")
        return ";".join(cells)

    warm.write_text("\n".join([lines[0], *map(warmer, lines[1:])]) + "\n")
    files = [*paths[:2], warm, *paths[3:]]
    other = tmp_path / "controller.yaml"
    other.write_text(
        cmap.read_text()
        .replace("{name: UF, unit: V}", "{name: UF, unit: V, base: 74}")
        .replace("{name: IF, unit: A}", "{name: IF, unit: A, base: 725}")
    )
    ohms = FIELD_BASE_V / FIELD_BASE_A
    for m in (cmap, other):
        bag = write_recording(tmp_path / f"{m.stem}.mcap", import_recordings(files, [m], kind="pmu"))
        found = field_resistance_of(cut_unit([bag]))
        r_f = found.as_dict() if found is not None else None
        assert r_f is not None and r_f["unit"] == "ohm"
        by_file = {name.rsplit("/", 1)[-1]: v for name, v in r_f["files"].items()}
        assert by_file["step_1"] == pytest.approx(1.08 * ohms, rel=0.003), m.name
        assert all(v == pytest.approx(ohms, rel=0.003) for f, v in by_file.items() if f != "step_1"), m.name
        assert r_f["range"] == pytest.approx([min(by_file.values()), max(by_file.values())])
    # the field in per unit: no bases, the figure is the recorder's own ratio (1 on the air-gap line)
    pu = tmp_path / "pu.yaml"
    pu.write_text(
        cmap.read_text()
        .replace("{name: UF, unit: V}", "{name: UF, unit: V, base: 123.4}")
        .replace("{name: IF, unit: A}", "{name: IF, unit: A, base: 1876}")
    )
    rec = import_recordings(files, [pu], kind="pmu")
    del rec.metadata["field_bases"]
    found = field_resistance_of(cut_unit([write_recording(tmp_path / "pu.mcap", rec)]))
    r_f = found.as_dict() if found is not None else None
    assert r_f is not None and r_f["unit"] == "U_f per I_f as recorded"
    assert sorted(r_f["files"].values())[0] == pytest.approx(1.0, rel=0.003)
