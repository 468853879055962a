"""COMTRADE in: waveforms synthesised from the simulator's phasors come back as the same identification.

The simulator's measured phasors (V_t, theta_t, I from i_d, i_q and delta) become three-phase
primary waveforms at 49.8 Hz on a 50 Hz system, with a 3 % fifth harmonic and 0.2 % noise,
written as COMTRADE with the recorder's other channels (P, Q in MW/Mvar, speed in Hz, load
angle in degrees, field voltage, mechanical power) and imported through a channel map.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from phid_ros.ident.pipeline import IdentifyOptions, identify
from phid_ros.io.field.channel_map import ChannelMapError, load_channel_map
from phid_ros.io.field.comtrade_import import ComtradeImportError, import_comtrade
from phid_ros.model.conventions import dq_to_terminal
from phid_ros.model.parameters import PARAMETER_NAMES
from phid_ros.sim.recording import recording_from_runs
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import paper_catalogue, with_duration
from phid_ros.stream.scenarios import scenarios_from_recording
from test.io.field.comtrade_writer import write_comtrade

# per test, not at module level: pytest 7 (the ROS tier's) skips the whole package for a module-level skip
pytestmark = pytest.mark.usefixtures("comtrade_available")


@pytest.fixture
def comtrade_available() -> None:
    pytest.importorskip("comtrade")


F_GRID = 49.8
FS = 1000.0
MVA, KV = 1000.0, 20.0
V_BASE = KV * 1e3 / math.sqrt(3)
I_BASE = MVA * 1e6 / (math.sqrt(3) * KV * 1e3)
MAP = f"""
machine: {{mva: {MVA}, kv: {KV}, f_nominal_hz: 50}}
channels:
  v_a: VA
  v_b: VB
  v_c: VC
  i_a: IA
  i_b: IB
  i_c: IC
  p_e: {{name: P, unit: MW}}
  q_e: {{name: Q, unit: Mvar}}
  omega: {{name: SPEED, unit: Hz}}
  load_angle: {{name: LOAD_ANGLE, unit: deg}}
  v_f: EFD
  p_m: {{name: PMECH, unit: MW}}
"""


def waveforms(m: dict[str, np.ndarray], rng: np.random.Generator) -> dict[str, tuple[np.ndarray, str]]:
    t = np.arange(len(m["v_t"])) / FS
    i_mag, i_ang = dq_to_terminal(m["i_d"], m["i_q"], m["delta"])
    out: dict[str, tuple[np.ndarray, str]] = {}
    for name, mag, ang, base, unit in (("V", m["v_t"], m["theta_t"], V_BASE, "V"), ("I", i_mag, i_ang, I_BASE, "A")):
        for k, phase in enumerate("ABC"):
            arg = 2 * np.pi * F_GRID * t + ang - 2 * np.pi * k / 3
            x = np.sqrt(2) * mag * base * (np.cos(arg) + 0.03 * np.cos(5 * arg))
            out[name + phase] = (x + 0.002 * np.sqrt(2) * base * rng.standard_normal(t.size), unit)
    out["P"] = (m["p_e"] * MVA, "MW")
    out["Q"] = (m["q_e"] * MVA, "Mvar")
    out["SPEED"] = (m["omega"] * F_GRID, "Hz")
    out["LOAD_ANGLE"] = (np.degrees(m["delta"] - m["theta_t"]), "deg")
    out["EFD"] = (m["v_f"], "pu")
    out["PMECH"] = (m["p_m"] * MVA, "MW")
    return out


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    folder = tmp_path_factory.mktemp("comtrade")
    scenarios = [with_duration(s, 12.0) for s in paper_catalogue()]
    cfg = SimulationConfig()
    runs = simulate_scenarios(scenarios, cfg)
    rng = np.random.default_rng(5)
    paths = []
    for k, run in enumerate(runs):
        n = run.n_analysis
        measured = {c: x[:n] for c, x in run.measured.items()}
        fmt = (
            ("ASCII", "1999", ".cfg")
            if k == 0
            else ("BINARY", "2013", ".cff")
            if k == 1
            else ("BINARY", "1999", ".cfg")
        )
        path = folder / f"{run.scenario.name}{fmt[2]}"
        write_comtrade(path, waveforms(measured, rng), FS, f_line=50.0, rev=fmt[1], ft=fmt[0])
        paths.append(path)
    kinds = "\n".join(
        f"  {s.name}: {{kind: {s.kind}, role: {s.role}, generator_damping: {str(s.generator_damping).lower()}}}"
        for s in scenarios
    )
    (folder / "map.yaml").write_text(MAP + "scenarios:\n" + kinds + "\n")
    direct = recording_from_runs([_analysis(r) for r in runs], cfg)
    return folder, paths, direct


def _analysis(run):
    from dataclasses import replace

    n = run.n_analysis
    cut = lambda d: {c: x[:n] for c, x in d.items()}  # noqa: E731
    return replace(run, t=run.t[:n], truth=cut(run.truth), states=cut(run.states), measured=cut(run.measured))


def test_comtrade_waveforms_identify_as_the_phasor_data(recordings) -> None:
    folder, paths, direct = recordings
    rec = import_comtrade(paths, load_channel_map(folder / "map.yaml"))
    assert [s.name for s in rec.scenarios] == [p.stem for p in paths]
    opts = IdentifyOptions(baseline=False, validate=False)
    via_comtrade = identify(scenarios_from_recording(rec, "comtrade")[0], opts).parameters
    via_phasors = identify(scenarios_from_recording(direct, "phasors")[0], opts).parameters
    diff = {n: 100 * (via_comtrade[n] / via_phasors[n] - 1) for n in PARAMETER_NAMES}
    print(diff)
    assert all(abs(d) < 0.5 for d in diff.values()), diff


def test_phid_import_comtrade_writes_a_set_identify_reads(recordings, tmp_path, capsys) -> None:
    from phid_ros.cli.main import main

    folder, paths, _ = recordings
    out = tmp_path / "set" / "manifest.json"
    argv = ["import-comtrade", *map(str, paths[:3]), "--map", str(folder / "map.yaml"), "--out", str(out)]
    assert main(argv) == 0
    manifest = json.loads(out.read_text())
    assert [e["file"] for e in manifest["scenarios"]] == [f"{p.stem}.csv" for p in paths[:3]]
    assert manifest["measurement_window_s"] == pytest.approx(0.02)  # kept through the CSV set
    assert main(argv) == 2 and "already exists" in capsys.readouterr().err


def small_recording(folder, *, fs: float = 1000.0, drop: str = "", ft: str = "ASCII") -> tuple:
    t = np.arange(int(fs * 0.6)) / fs
    ch = {}
    for k, p in enumerate("ABC"):
        ch["V" + p] = (np.sqrt(2) * V_BASE * np.cos(2 * np.pi * 50 * t - 2 * np.pi * k / 3), "V")
        ch["I" + p] = (np.sqrt(2) * 0.8 * I_BASE * np.cos(2 * np.pi * 50 * t - 0.5 - 2 * np.pi * k / 3), "A")
    ch.update({"SPEED": (np.full(t.size, 50.0), "Hz"), "LOAD_ANGLE": (np.full(t.size, 40.0), "deg")})
    ch.update({"EFD": (np.full(t.size, 2.0), "pu"), "PMECH": (np.full(t.size, 800.0), "MW")})
    ch.pop(drop, None)
    path = write_comtrade(folder / "rec.cfg", ch, fs, ft=ft)
    (folder / "map.yaml").write_text(MAP.replace("  p_e: {name: P, unit: MW}\n  q_e: {name: Q, unit: Mvar}\n", ""))
    return path, load_channel_map(folder / "map.yaml")


def test_a_clean_recording_is_converted_exactly(tmp_path) -> None:
    path, cmap = small_recording(tmp_path, ft="BINARY")
    rec = import_comtrade([path], cmap)
    c = rec.streams
    pt_ct, pmu = c["pt_ct"].channels, c["pmu"].channels
    assert np.allclose(pt_ct["v_t"], 1.0, atol=2e-4) and np.allclose(pt_ct["p_e"], 0.8 * np.cos(0.5), atol=5e-4)
    assert np.allclose(pmu["delta"] - pmu["theta_t"], np.radians(40), atol=1e-6)
    assert np.allclose(c["encoder"].channels["omega"], 1.0, atol=1e-6)
    assert "not_imported" not in rec.metadata and not any("not imported" in w for w in rec.warnings)


def test_an_analog_channel_no_map_names_is_said_left_behind(tmp_path) -> None:
    path, cmap = small_recording(tmp_path)
    text = (tmp_path / "map.yaml").read_text()
    (tmp_path / "map.yaml").write_text(text.replace("  p_m: {name: PMECH, unit: MW}\n", ""))
    rec = import_comtrade([path], load_channel_map(tmp_path / "map.yaml"))
    assert "recorded but named by no channel map, so not imported: PMECH (rec)" in rec.warnings[-1]
    assert rec.metadata["not_imported"] == "PMECH" and "p_m" in rec.metadata["not_recorded"]


def test_bad_recordings_are_named(tmp_path) -> None:
    path, cmap = small_recording(tmp_path)
    dat = path.with_suffix(".dat")
    lines = dat.read_text().splitlines()
    dat.write_text("\n".join(",".join(r.split(",")[:-1]) for r in lines) + "\n")  # one channel short
    with pytest.raises(
        ComtradeImportError, match=r"rec\.dat: rows carry \[11\] values but rec\.cfg declares 10 analog"
    ):
        import_comtrade([path], cmap)
    rows = [r.split(",") for r in lines]
    rows[5][1], rows[6][1] = rows[6][1], rows[5][1]
    dat.write_text("\n".join(",".join(r) for r in rows) + "\n")
    # with a rate in the .cfg the stamps are non-critical (C37.111): times from the rate, and a note
    rec = import_comtrade([path], cmap)
    assert any(
        "sample times taken from the .cfg's rate (1000 Hz); the stamps are wrapped or uneven" in w for w in rec.warnings
    )
    path, cmap = small_recording(tmp_path, fs=800.0)
    with pytest.raises(ComtradeImportError, match=r"rec\.cfg: sampling rate 800 Hz is below the 960 Hz"):
        import_comtrade([path], cmap)
    path, cmap = small_recording(tmp_path, drop="EFD")
    with pytest.raises(ChannelMapError, match=r"channel 'EFD' for v_f is not in rec\.cfg \(channels: VA, IA"):
        import_comtrade([path], cmap)


def test_bad_maps_are_named(tmp_path) -> None:
    path, _ = small_recording(tmp_path)
    m = tmp_path / "map.yaml"
    # a channel the recorder did not carry is left out of the map, and comes out not recorded (NaN)
    pq = "  p_e: {name: P, unit: MW}\n  q_e: {name: Q, unit: Mvar}\n"
    m.write_text(MAP.replace("  v_f: EFD\n", "").replace(pq, ""))
    rec = import_comtrade([path], load_channel_map(m))
    assert np.isnan(rec.streams["excitation"].channels["v_f"]).all()
    assert np.isfinite(rec.streams["pt_ct"].channels["i_d"]).all()
    no_current = "".join(f"  i_{p}: I{p.upper()}\n" for p in "abc")
    m.write_text(MAP.replace(no_current, "").replace(pq, ""))
    with pytest.raises(ChannelMapError, match=r"no channel mapped for the stator current .*; rec\.cfg has: VA, IA, VB"):
        import_comtrade([path], load_channel_map(m))
    m.write_text(MAP.replace("  i_a: IA", "  i_a: {name: IA, side: secondary}"))
    with pytest.raises(ChannelMapError, match=r"i_a \(IA\) is a secondary value but the map gives no CT ratio"):
        load_channel_map(m)
    m.write_text(MAP.replace("  i_a: IA", "  i_a: {name: IA, side: secondary}") + "ratios: {ct: 30000/1}\n")
    assert load_channel_map(m).ratio(load_channel_map(m).channels["i_a"]) == 30000.0
    m.write_text(MAP.replace("unit: Hz", "unit: furlongs"))
    with pytest.raises(ChannelMapError, match=r"omega unit 'furlongs' not one of pu, Hz, rpm"):
        load_channel_map(m)


def _habit_recording(folder, fs: float, **habits) -> tuple:
    """small_recording's unit (V_t = 1, P = 0.8 cos 0.5 pu, load angle 40 deg) with a recorder's habit."""
    n = int(fs * 0.6) if habits.get("t") is None else len(habits["t"])
    t = np.arange(n) / fs if habits.get("t") is None else habits.pop("t")
    ch = {}
    for k, p in enumerate("ABC"):
        ch["V" + p] = (np.sqrt(2) * V_BASE * np.cos(2 * np.pi * 50 * t - 2 * np.pi * k / 3), "V")
        ch["I" + p] = (np.sqrt(2) * 0.8 * I_BASE * np.cos(2 * np.pi * 50 * t - 0.5 - 2 * np.pi * k / 3), "A")
    ch.update({"SPEED": (np.full(n, 50.0), "Hz"), "LOAD_ANGLE": (np.full(n, 40.0), "deg")})
    ch.update({"EFD": (np.full(n, 2.0), "pu"), "PMECH": (np.full(n, 800.0), "MW")})
    path = write_comtrade(folder / "rec.cfg", ch, fs, **habits)
    (folder / "map.yaml").write_text(MAP.replace("  p_e: {name: P, unit: MW}\n  q_e: {name: Q, unit: Mvar}\n", ""))
    return path, load_channel_map(folder / "map.yaml")


def _as_the_unit(rec) -> None:
    pt_ct, pmu = rec.streams["pt_ct"].channels, rec.streams["pmu"].channels
    assert np.allclose(pt_ct["v_t"], 1.0, atol=5e-4) and np.allclose(pt_ct["p_e"], 0.8 * np.cos(0.5), atol=1e-3)
    assert np.allclose(pmu["delta"] - pmu["theta_t"], np.radians(40), atol=1e-6)


@pytest.mark.parametrize(
    "habit, note",
    [
        ({"stamps": np.round(np.arange(600) * 1e3).astype(np.int64) % (1 << 16)}, "the stamps are wrapped or uneven"),
        ({"stamps": np.zeros(600, dtype=np.int64)}, "the stamps are all 0"),
        ({"ft": "BINARY", "pad": 37}, None),  # SEL relays pad the .dat with 0x1A to a block
    ],
    ids=["stamps-wrapped-at-2^16-us", "stamps-all-zero", "dat-padded-with-0x1A"],
)
def test_recorder_habits_c37_111_allows_are_read(tmp_path, habit, note) -> None:
    """6 of 9 real COMTRADE files were refused before their channel map was read."""
    path, cmap = _habit_recording(tmp_path, 1000.0, **habit)
    rec = import_comtrade([path], cmap)
    _as_the_unit(rec)
    if note:
        assert any(f"rec.cfg: sample times taken from the .cfg's rate (1000 Hz); {note}" in w for w in rec.warnings)


def test_an_off_grid_rate_and_a_frequency_tracking_recorder_are_resampled(tmp_path) -> None:
    """5760 Hz at 50 Hz (115.2 samples a cycle), and nrates 0 with uneven steps around 1001.6 Hz:
    resampled to a whole number of samples per cycle, and the note says by how much."""
    path, cmap = _habit_recording(tmp_path, 5760.0)
    rec = import_comtrade([path], cmap)
    _as_the_unit(rec)
    assert any(
        "resampled from 115.200 samples per 50 Hz cycle to 5800 Hz (116 per cycle) by a cubic spline" in w
        for w in rec.warnings
    )
    rng = np.random.default_rng(3)
    steps = (1.0 / 1001.6) * (1 + 0.02 * rng.uniform(-1, 1, 700))
    t = np.concatenate(([0.0], np.cumsum(steps)))[:700]
    (tmp_path / "b").mkdir()
    path, cmap = _habit_recording(
        tmp_path / "b", 1001.6, t=t, stamps=np.round(t * 1e6).astype(np.int64), declare_rate=False
    )
    rec = import_comtrade([path], cmap)
    _as_the_unit(rec)
    assert any("resampled from uneven steps to 1050 Hz (21 per cycle) by a cubic spline" in w for w in rec.warnings)


def test_the_recording_starts_when_its_cfg_says(tmp_path) -> None:
    path, cmap = _habit_recording(tmp_path, 1000.0, start="20/09/2015,12:52:35.236463")
    rec = import_comtrade([path], cmap)
    from datetime import datetime, timezone

    start = datetime(2015, 9, 20, 12, 52, 35, 236463, tzinfo=timezone.utc).timestamp()
    assert rec.span_ns()[0] == pytest.approx(start * 1e9, abs=1e6)  # within the phasor's half cycle


@pytest.mark.parametrize("ft", ["BINARY", "ASCII"])
def test_a_recording_converted_in_blocks_is_the_one_converted_whole(tmp_path, ft, monkeypatch) -> None:
    """Blocks of 97 phasors (margins, angles unwrapped across the joins, decimation from 2 kHz)
    give the outcome of one block, to rounding; and the recording's data are read in chunks."""
    from phid_ros.io.field import comtrade_dat, phasors

    path, cmap = _habit_recording(tmp_path, 2000.0, ft=ft)
    monkeypatch.setattr(phasors, "BLOCK", 1 << 30)
    whole = import_comtrade([path], cmap).streams
    monkeypatch.setattr(phasors, "BLOCK", 97)
    monkeypatch.setattr(comtrade_dat, "CHUNK_ROWS", 101)
    pieces = import_comtrade([path], cmap).streams
    for name, st in whole.items():
        assert np.array_equal(st.t_ns, pieces[name].t_ns)
        for c, x in st.channels.items():
            assert np.allclose(pieces[name].channels[c], x, rtol=0, atol=1e-9, equal_nan=True), (name, c)
    assert len(whole["pt_ct"].t_ns) == (1200 - 40 + 1 + 1) // 2  # 2 kHz decimated to 1 kHz


@pytest.mark.parametrize(
    ("swap", "message"),
    [
        ({"v_b": "VC", "v_c": "VB"}, r"v_a: VA, v_b: VC, v_c: VB: negative sequence 1\.00 of a phase, positive 0\.00"),
        # one column mapped as three quantities is refused by the map itself, before any sample
        ({"i_b": "IA", "i_c": "IA"}, r"the column 'IA' is mapped as i_a and i_b and i_c: a column is one quantity"),
    ],
)
def test_phases_swapped_or_one_channel_on_three_are_named(tmp_path, swap, message) -> None:
    """B and C swapped in the map, or one channel mapped to all three phases: exit 0 with X_d
    -3.6e4 (withheld) and no word before. Now the first cycle's sequences name the mapping."""
    path, _ = small_recording(tmp_path)
    text = MAP.replace("  p_e: {name: P, unit: MW}\n  q_e: {name: Q, unit: Mvar}\n", "")
    for q, name in swap.items():
        text = text.replace(f"  {q}: {q[0].upper()}{q[2].upper()}\n", f"  {q}: {name}\n")
    (tmp_path / "swapped.yaml").write_text(text)
    with pytest.raises((ComtradeImportError, ChannelMapError), match=message):
        import_comtrade([path], load_channel_map(tmp_path / "swapped.yaml"))


def test_a_recorder_whose_phases_turn_acb_is_read_with_its_rotation_declared(tmp_path) -> None:
    """A relay whose phases turn A-C-B (its B carries what an A-B-C recorder's C does) was refused
    as "B and C swapped", with no way to say so but to exchange the two in the map. Declared as
    ``rotation: acb`` it imports as the same recording read A-B-C."""
    path, cmap = small_recording(tmp_path)
    reference = import_comtrade([path], cmap).streams
    cfg = path.read_text()
    # relabel: the recorder's B is the A-B-C system's C and the other way round (analog names only)
    swapped = cfg.replace(",VB,", ",TMP,").replace(",VC,", ",VB,").replace(",TMP,", ",VC,")
    swapped = swapped.replace(",IB,", ",TMP,").replace(",IC,", ",IB,").replace(",TMP,", ",IC,")
    assert swapped != cfg
    path.write_text(swapped)
    with pytest.raises(ComtradeImportError, match=r"phases turn A-C-B \(then say rotation: acb in the map\)"):
        import_comtrade([path], cmap)
    (tmp_path / "acb.yaml").write_text((tmp_path / "map.yaml").read_text() + "rotation: acb\n")
    acb = import_comtrade([path], load_channel_map(tmp_path / "acb.yaml")).streams
    for name, st in reference.items():
        for c, x in st.channels.items():
            assert np.allclose(acb[name].channels[c], x, rtol=0, atol=1e-12, equal_nan=True), (name, c)
    (tmp_path / "bad.yaml").write_text((tmp_path / "map.yaml").read_text() + "rotation: cba\n")
    with pytest.raises(ChannelMapError, match=r"bad\.yaml: rotation 'cba' must be one of abc, acb"):
        load_channel_map(tmp_path / "bad.yaml")


def test_a_dat_shorter_than_its_cfg_declares_is_said(tmp_path) -> None:
    """A .cfg declaring 1200 samples beside a .dat of 600 imported as a shorter recording, no word."""
    path, cmap = small_recording(tmp_path, ft="BINARY")
    cfg = path.read_text().splitlines()
    k = next(i for i, line in enumerate(cfg) if line.strip().endswith(",600"))
    cfg[k] = cfg[k].replace(",600", ",1200")
    path.write_text("\n".join(cfg) + "\n")
    rec = import_comtrade([path], cmap)
    assert any("rec.dat: holds 600 of the 1200 samples rec.cfg declares (50 %)" in w for w in rec.warnings)


def test_a_cfg_declaring_more_channels_than_it_has_lines_is_refused_before_parsing(tmp_path) -> None:
    path, cmap = small_recording(tmp_path)
    cfg = path.read_text().splitlines()
    cfg[1] = "2000000003,2000000000A,3D"
    path.write_text("\n".join(cfg[:6]) + "\n")
    with pytest.raises(ComtradeImportError, match=r"rec\.cfg: declares 2000000003 channels on its second line but"):
        import_comtrade([path], cmap)


def test_a_cfg_whose_channel_counts_disagree_is_refused(tmp_path) -> None:
    path, cmap = small_recording(tmp_path)
    cfg = path.read_text().splitlines()
    total = int(cfg[1].split(",")[0])
    cfg[1] = f"{total},2000000000A,0D"
    path.write_text("\n".join(cfg) + "\n")
    with pytest.raises(ComtradeImportError, match=r"declares 2000000000 analog and 0 status channels, which is not"):
        import_comtrade([path], cmap)
