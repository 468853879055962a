"""PMU exports in: phasor columns through the channel map give the simulator's channels back."""

from __future__ import annotations

import numpy as np
import pytest

from phid_ros.io.field.channel_map import ChannelMapError, load_channel_map
from phid_ros.io.field.pmu_csv import PmuImportError, import_pmu_csv
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import find_scenario, with_duration
from test.io.field.field_sets import phasor_columns, pmu_lines

KV, MVA = 20.0, 1000.0
V_BASE = KV * 1e3 / np.sqrt(3)
I_BASE = MVA * 1e6 / (np.sqrt(3) * KV * 1e3)
STEP = 10  # 1 kHz simulation -> 100 reports per second
MAP = """
machine: {mva: 1000, kv: 20, f_nominal_hz: 50, phasor_window_cycles: 2}
time: Timestamp
channels:
  v_t: {name: "GEN1:V1_MAG", unit: V}
  theta_t: {name: "GEN1:V1_ANG", unit: deg}
  i_t: {name: "GEN1:I1_MAG", unit: A}
  phi_i: {name: "GEN1:I1_ANG", unit: deg}
  omega: {name: SPEED, unit: pu}
  delta: {name: ROTOR_ANGLE, unit: deg}
  v_f: EFD
  p_m: {name: PMECH, unit: MW}
scenarios:
  S09: {kind: voltage_step, event_time_s: 1.0}
"""


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pmu")
    run = simulate_scenarios([with_duration(find_scenario("S09"), 6.0)], SimulationConfig())[0]
    m = {c: x[: run.n_analysis : STEP] for c, x in run.measured.items()}
    cols = phasor_columns(m, STEP, "GEN1")
    cols.update(
        {
            "GEN1:FREQ": 50.0 * m["omega"],
            "SPEED": m["omega"],
            "ROTOR_ANGLE": np.degrees(m["delta"]),
            "EFD": m["v_f"],
            "PMECH": m["p_m"] * MVA,
        }
    )
    lines = pmu_lines(cols)
    path = folder / "S09.csv"
    path.write_text("\n".join(lines) + "\n")
    (folder / "map.yaml").write_text(MAP)
    return path, load_channel_map(folder / "map.yaml"), m


def test_pmu_export_gives_the_channels_back(export) -> None:
    path, cmap, m = export
    rec = import_pmu_csv([path], cmap)
    [sc] = rec.scenarios
    assert (sc.name, sc.kind) == ("S09", "voltage_step") and sc.event_ns - sc.start_ns == 1_000_000_000
    assert rec.streams["pt_ct"].period_ns == 10_000_000 and rec.metadata["measurement_window_s"] == repr(0.04)
    got = {c: x for s in rec.streams.values() for c, x in s.channels.items()}
    for c in ("v_t", "i_d", "i_q", "v_f", "p_m"):
        assert np.allclose(got[c], m[c], atol=1e-9), c
    assert np.allclose(got["delta"] - got["theta_t"], m["delta"] - m["theta_t"], atol=1e-9)
    # the synchronous frame is the frequency before the event, fitted from the angle: a tiny ramp at most
    ramp = (got["theta_t"] - m["theta_t"]) - (got["theta_t"] - m["theta_t"])[0]
    assert np.max(np.abs(ramp)) < 5e-3 and np.allclose(got["omega"], m["omega"], rtol=2e-5)
    assert np.allclose(got["p_e"], m["p_e"], atol=0.02)  # from V and I: the sensors' own noise differs
    # the concentrator's frequency column, which the map names for nothing, is left behind: said so
    assert "recorded but named by no channel map, so not imported: GEN1:FREQ (S09)" in rec.warnings[-1]
    assert rec.metadata["not_imported"] == "GEN1:FREQ"


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda rows: rows.__setitem__(5, rows[6]), r"S09\.csv: report times do not increase \(line 7"),
        (lambda rows: rows.pop(9), r"S09\.csv: reports missing at line 10: 20\.000 ms after the previous, at 0\.090 s"),
        (lambda rows: rows.__setitem__(0, rows[0].replace("EFD", "E_FD")), r"channel 'EFD' for v_f is not in S09\.csv"),
        (lambda rows: rows.__setitem__(4, rows[4].rsplit(",", 1)[0] + ",n/a"), r"line 5, column 'PMECH': 'n/a'"),
    ],
)
def test_bad_exports_are_named(export, tmp_path, edit, message) -> None:
    path, cmap, _ = export
    rows = path.read_text().splitlines()
    edit(rows)
    bad = tmp_path / "S09.csv"
    bad.write_text("\n".join(rows) + "\n")
    with pytest.raises((PmuImportError, ChannelMapError), match=message):
        import_pmu_csv([bad], cmap)


def test_a_trend_log_with_date_and_time_of_day_and_a_jittered_clock_is_read(export, tmp_path) -> None:
    """An excitation controller's trend log: a date column 20.09.2015 beside a time of day
    12:52:35.2364630, about 100 reports a second jittered by +-0.3 ms, ';' fields with decimal
    commas. Refused before ("reports missing or uneven"); now resampled onto its period."""
    path, cmap, _ = export
    plain = import_pmu_csv([path], cmap)
    rows = path.read_text().splitlines()
    head = rows[0].split(",")
    rng = np.random.default_rng(5)
    start = 12 * 3600 + 52 * 60 + 35.236463
    out = [";".join(["Date", "Time", *head[1:]])]
    jitter = rng.uniform(-3e-4, 3e-4, len(rows) - 1)
    for k, row in enumerate(rows[1:]):
        secs = start + 0.01 * k + jitter[k]
        h, rem = divmod(secs, 3600)
        m, s = divmod(rem, 60)
        fields = row.split(",")[1:]
        out.append(
            ";".join(["20.09.2015", f"{int(h):02d}:{int(m):02d}:{s:010.7f}", *(f.replace(".", ",") for f in fields)])
        )
    log = tmp_path / "S09.csv"
    log.write_text("\r\n".join(out) + "\r\n")
    (tmp_path / "map.yaml").write_text(MAP.replace("time: Timestamp", "time: Time\ndate: Date"))
    rec = import_pmu_csv([log], load_channel_map(tmp_path / "map.yaml"))
    assert any("report times jitter by up to 0." in w and "resampled onto 100 per s" in w for w in rec.warnings)
    for stream in ("pt_ct", "pmu", "encoder"):
        for c, want in plain.streams[stream].channels.items():
            got = rec.streams[stream].channels[c]
            assert got.shape == want.shape
            # a 0.3 ms shift of a 100 Hz report of slow phasors: a few 1e-4 pu at the steps
            assert np.allclose(got, want, atol=5e-3), (stream, c, float(np.max(np.abs(got - want))))


def test_an_export_read_a_chunk_at_a_time_is_read_as_whole(export, tmp_path, monkeypatch) -> None:
    """Chunks of 7 reports (the file's 600 in 86 chunks) give the channels of one chunk, and a
    bad entry deep in the file is named by its line, after the time checks as before."""
    from phid_ros.io.field import pmu_csv

    path, cmap, _ = export
    whole = import_pmu_csv([path], cmap)
    monkeypatch.setattr(pmu_csv, "CHUNK_ROWS", 7)
    chunked = import_pmu_csv([path], cmap)
    for name, stream in whole.streams.items():
        assert np.array_equal(stream.t_ns, chunked.streams[name].t_ns)
        for c, x in stream.channels.items():
            assert np.array_equal(x, chunked.streams[name].channels[c], equal_nan=True), (name, c)
    rows = path.read_text().splitlines()
    for line, edit, message in [
        (400, lambda r: r.rsplit(",", 1)[0] + ",inf", r"line 400, column 'PMECH': 'inf' is not finite"),
        (401, lambda r: r + ",1.0", r"line 401 has 11 fields, the header 10"),
        (402, lambda r: "12.5" + r[r.index(",") :], r"line 402, column 'Timestamp': '12\.5' is not a time \(iso"),
    ]:
        bad = rows.copy()
        bad[line - 1] = edit(bad[line - 1])
        (tmp_path / "S09.csv").write_text("\n".join(bad) + "\n")
        with pytest.raises(PmuImportError, match=message):
            import_pmu_csv([tmp_path / "S09.csv"], cmap)


@pytest.mark.parametrize("reports", [0, 1])
def test_an_export_without_two_reports_is_refused(export, tmp_path, reports) -> None:
    path, cmap, _ = export
    (tmp_path / "S09.csv").write_text("\n".join(path.read_text().splitlines()[: 1 + reports]) + "\n")
    with pytest.raises(PmuImportError, match=r"S09\.csv: needs a header row and at least two reports"):
        import_pmu_csv([tmp_path / "S09.csv"], cmap)


def test_a_trend_log_with_thousands_points_and_a_one_digit_hour_reads_as_the_plain_export(export, tmp_path) -> None:
    """A decimal-comma trend log writes P in kW as 802.637 (802 637 kW) and its times of day as
    9:00:00.0000000. Before: every ',' became '.', the '.' stayed, P_m was read 1000x small
    without a word (X_d +81 % published as identified), and the one-digit hour was "not a time"."""
    path, cmap, _ = export
    plain = import_pmu_csv([path], cmap)
    rows = path.read_text().splitlines()
    head = rows[0].split(",")
    k_pm = head.index("PMECH")
    out = [";".join(["Date", "Time", *head[1:]])]
    for k, row in enumerate(rows[1:]):
        secs = 9 * 3600 + 0.01 * k
        clock = f"{int(secs // 3600)}:{int(secs % 3600 // 60):02d}:{secs % 60:010.7f}"  # 9:00:00.0000000
        fields = row.split(",")
        fields[k_pm] = f"{float(fields[k_pm]) * 1e3:,.3f}".replace(",", " ").replace(".", ",").replace(" ", ".")
        cells = [f.replace(".", ",") if j != k_pm else f for j, f in enumerate(fields)]
        out.append(";".join(["20.09.2015", clock, *cells[1:]]))
    assert "9:00:00.0000000" in out[1] and "." in out[1].split(";")[k_pm + 1]
    log = tmp_path / "S09.csv"
    log.write_text("\n".join(out) + "\n")
    in_kw = MAP.replace("{name: PMECH, unit: MW}", "{name: PMECH, unit: kW}")
    (tmp_path / "map.yaml").write_text(in_kw.replace("time: Timestamp", "time: Time\ndate: Date"))
    rec = import_pmu_csv([log], load_channel_map(tmp_path / "map.yaml"))
    p_m = rec.streams["encoder"].channels["p_m"]
    assert np.allclose(p_m, plain.streams["encoder"].channels["p_m"], rtol=1e-6), float(np.nanmax(p_m))
    out[5] = out[5].replace(out[5].split(";")[k_pm + 1], "802.63", 1)  # a point that groups nothing
    log.write_text("\n".join(out) + "\n")
    with pytest.raises(PmuImportError, match=r"line 6, column 'PMECH': '802\.63' has a point that does not group"):
        import_pmu_csv([log], load_channel_map(tmp_path / "map.yaml"))


def test_an_export_whose_decimal_mark_changes_midway_is_refused(export, tmp_path, monkeypatch) -> None:
    from phid_ros.io.field import pmu_csv

    path, cmap, _ = export
    rows = path.read_text().splitlines()
    out = [rows[0].replace(",", ";")] + [r.replace(",", ";") for r in rows[1:]]  # ';' with decimal points
    out[300] = out[300].replace(".", ",")
    log = tmp_path / "S09.csv"
    log.write_text("\n".join(out) + "\n")
    monkeypatch.setattr(pmu_csv, "CHUNK_ROWS", 100)
    with pytest.raises(PmuImportError, match=r"line 301, column '.*' has a decimal comma where the reports before"):
        import_pmu_csv([log], cmap)
    out[300] = out[300].replace(",", ".")
    log.write_text("\n".join(out) + "\n")
    plain = import_pmu_csv([path], cmap)
    got = import_pmu_csv([log], cmap)
    assert np.array_equal(got.streams["pt_ct"].channels["v_t"], plain.streams["pt_ct"].channels["v_t"])


NO_LOAD_MAP = """
machine: {mva: 30, kv: 10.5, f_nominal_hz: 50}
time: Timestamp
channels:
  v_t: {name: UG, unit: pu}
  v_f: {name: UF, unit: pu}
"""
ON_LINE_MAP = (
    NO_LOAD_MAP
    + """  p_e: {name: P, unit: pu}
  q_e: {name: Q, unit: pu}
"""
)


def _trend_log(path, columns: dict) -> None:
    n = len(next(iter(columns.values())))
    rows = ["Timestamp," + ",".join(columns)]
    rows += [f"{k * 0.005:.4f}," + ",".join(f"{columns[c][k]:.6f}" for c in columns) for k in range(n)]
    path.write_text("\n".join(rows) + "\n")


def test_a_no_load_test_imports_as_an_open_circuit_and_each_file_takes_the_map_it_fits(tmp_path) -> None:
    n = 800
    _trend_log(tmp_path / "noload.csv", {"UG": np.full(n, 1.0), "UF": np.full(n, 0.37)})
    _trend_log(
        tmp_path / "online.csv",
        {"UG": np.full(n, 1.0), "UF": np.full(n, 0.6), "P": np.full(n, 0.5), "Q": np.full(n, 0.2)},
    )
    (tmp_path / "noload.yaml").write_text(NO_LOAD_MAP)
    (tmp_path / "online.yaml").write_text(ON_LINE_MAP)
    maps = [load_channel_map(tmp_path / "noload.yaml"), load_channel_map(tmp_path / "online.yaml")]
    rec = import_pmu_csv([tmp_path / "noload.csv", tmp_path / "online.csv"], maps)
    pt = rec.streams["pt_ct"]
    first = pt.t_ns <= rec.scenarios[0].end_ns
    # open circuit: P = Q = I = 0, said so (I_d, I_q, like the rotor angle, not recorded: NaN); the
    # on-line file through the fuller map keeps its P and Q
    for c in ("p_e", "q_e"):
        assert np.all(pt.channels[c][first] == 0.0)
    assert np.isnan(pt.channels["i_d"]).all() and rec.metadata["not_recorded"] == "i_d,i_q,omega,delta,p_m"
    assert np.allclose(pt.channels["p_e"][~first], 0.5) and np.allclose(pt.channels["q_e"][~first], 0.2)
    assert sum("no stator quantity mapped" in w for w in rec.warnings) == 1
    # a map of V_t alone is no open circuit: it carries nothing to identify
    (tmp_path / "v_only.yaml").write_text(NO_LOAD_MAP.replace("  v_f: {name: UF, unit: pu}\n", ""))
    with pytest.raises(ChannelMapError, match="no channel mapped for the stator current"):
        import_pmu_csv([tmp_path / "noload.csv"], load_channel_map(tmp_path / "v_only.yaml"))
    # maps of two machines are not one set
    (tmp_path / "other.yaml").write_text(ON_LINE_MAP.replace("mva: 30", "mva: 40"))
    with pytest.raises(ChannelMapError, match="the maps of one set describe one unit"):
        import_pmu_csv([tmp_path / "noload.csv"], [maps[0], load_channel_map(tmp_path / "other.yaml")])


def test_the_voltage_phasor_as_its_real_and_imaginary_parts_reads_as_magnitude_and_angle(export, tmp_path) -> None:
    """A recorder (or another tool) that exports the terminal phasor as V_re, V_im (the Itaipu
    record shipped with RaPId): v_re and v_im in the map give the channels the magnitude and angle
    give, to rounding. Mapped beside v_t, or one part alone, the map is refused in one line."""
    path, cmap, m = export
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    k_mag, k_ang = header.index("GEN1:V1_MAG"), header.index("GEN1:V1_ANG")
    rows = [line.split(",") for line in lines[1:]]
    for r in rows:
        v = float(r[k_mag]) * np.exp(1j * np.radians(float(r[k_ang])))
        r[k_mag], r[k_ang] = repr(float(v.real)), repr(float(v.imag))
    header[k_mag], header[k_ang] = "GEN1:V1_RE", "GEN1:V1_IM"
    rect = tmp_path / "S09.csv"
    rect.write_text("\n".join([",".join(header)] + [",".join(r) for r in rows]) + "\n")
    text = MAP.replace(
        '  v_t: {name: "GEN1:V1_MAG", unit: V}\n  theta_t: {name: "GEN1:V1_ANG", unit: deg}\n',
        '  v_re: {name: "GEN1:V1_RE", unit: V}\n  v_im: {name: "GEN1:V1_IM", unit: V}\n',
    )
    (tmp_path / "rect.yaml").write_text(text)
    want = import_pmu_csv([path], cmap)
    got = import_pmu_csv([rect], load_channel_map(tmp_path / "rect.yaml"))
    for name, s in want.streams.items():
        for c, x in s.channels.items():
            np.testing.assert_allclose(got.streams[name].channels[c], x, rtol=1e-9, atol=1e-9, err_msg=c)
    both = text.replace("  v_re:", '  v_t: {name: "GEN1:V1_MAG", unit: V}\n  v_re:')
    (tmp_path / "both.yaml").write_text(both)
    with pytest.raises(ChannelMapError, match=r"the terminal voltage is mapped as v_t, v_re, v_im: map it once"):
        import_pmu_csv([rect], load_channel_map(tmp_path / "both.yaml"))
    (tmp_path / "half.yaml").write_text(text.replace('  v_im: {name: "GEN1:V1_IM", unit: V}\n', ""))
    with pytest.raises(ChannelMapError, match=r"mapped as v_re: map it once, as v_t \(with theta_t\) or as both"):
        import_pmu_csv([rect], load_channel_map(tmp_path / "half.yaml"))


def test_a_controllers_own_signals_travel_to_the_scenarios_and_an_on_line_test_is_never_read_as_no_load(
    tmp_path,
) -> None:
    """The regulator's and the stabiliser's outputs and the field current go into the bag on a
    stream of their own and come back on each scenario's samples (to the recorded digits), as does
    the test sheet's reference step (a map's ``reference_step``) through the markers; the
    stabiliser's output, kept only in the test it was on for, is left out of the others with a
    note. An on-line file the on-line map does not fit is refused, not read as an open circuit."""
    from phid_ros.api import cut_scenarios
    from phid_ros.io.bags.recordings import write_recording

    n = 1200
    t = np.arange(n) * 0.005
    step = (t >= 3.0).astype(float)
    v_s = 0.01 * np.sin(2 * np.pi * 1.3 * t) * (t >= 1.0)
    v_r = 1.2 + 3.0 * step * np.exp(-np.maximum(t - 3.0, 0.0) / 0.05)
    online = {"UG": 1.0 + 0.03 * step, "UF": 0.6 + 0.1 * step, "P": np.full(n, 0.5), "Q": 0.2 + 0.1 * step}
    _trend_log(tmp_path / "pss_on.csv", {**online, "IF": 0.8 + 0.1 * step, "UREG": v_r, "VPSS": v_s})
    status = {"STATUS": np.full(n, 3.0)}  # a status word no map names
    off = {**online, "Q": online["Q"] + 0.05, "IF": 0.8 + 0.1 * step, "UREG": v_r}
    _trend_log(tmp_path / "pss_off.csv", off | status)
    extra = "  i_fd: {name: IF, unit: pu}\n  v_r: UREG\n  v_s: VPSS\n"
    (tmp_path / "online.yaml").write_text(
        ON_LINE_MAP
        + extra
        + "scenarios:\n  pss_on: {kind: field_step, reference_step: 0.05}\n  pss_off: {kind: field_step}\n"
    )
    (tmp_path / "noload.yaml").write_text(NO_LOAD_MAP + "  i_fd: {name: IF, unit: pu}\n  v_r: UREG\n")
    maps = [load_channel_map(tmp_path / "noload.yaml"), load_channel_map(tmp_path / "online.yaml")]
    rec = import_pmu_csv([tmp_path / "pss_on.csv", tmp_path / "pss_off.csv"], maps)
    assert set(rec.recorder_streams()) == {"field_controller"}
    assert any("pss_off.csv: no v_s (VPSS) in this file: imported without it" in w for w in rec.warnings)
    assert not any("no stator quantity mapped" in w for w in rec.warnings)  # both read on line
    left = "recorded but named by no channel map, so not imported: STATUS (pss_off) (map them to use them"
    assert any(w.startswith(left) for w in rec.warnings) and rec.metadata["not_imported"] == "STATUS"
    write_recording(tmp_path / "set.mcap", rec)
    scs = {s.name: s for s in cut_scenarios(tmp_path / "set.mcap").scenarios}
    on, off = scs["pss_on"], scs["pss_off"]
    assert on.has("v_s", "v_r", "i_fd") and off.has("v_r", "i_fd") and not off.has("v_s")
    # on the scenario's samples, as written (six decimals in the file)
    k = np.arange(on.n)
    assert np.allclose(on["v_s"], np.round(v_s[k], 6), atol=1e-12)
    assert np.allclose(on["v_r"], np.round(v_r[k], 6), atol=1e-12)
    assert np.allclose(off["i_fd"], np.round(0.8 + 0.1 * step[k], 6), atol=1e-12)
    assert on.k_event == 600
    assert (on.reference_step, off.reference_step) == (0.05, None)  # the test sheet's, through the bag
    # a CSV set written from the import reads back with them (as %.9g writes them)
    from phid_ros.io.csvset.csv_export import write_csv_set
    from phid_ros.io.csvset.csv_import import import_csv_set

    back = import_csv_set(write_csv_set(tmp_path / "set", rec))
    mine, theirs = rec.streams["field_controller"].channels, back.streams["field_controller"].channels
    for c in ("i_fd", "v_r", "v_s"):
        assert np.allclose(theirs[c], mine[c], rtol=1e-8, atol=1e-15, equal_nan=True)
    assert np.isnan(theirs["v_s"][n:]).all() and np.isfinite(theirs["v_s"][:n]).all()
    assert [s.reference_step for s in back.scenarios] == [0.05, None]
    # an on-line file without the on-line map's E_fd column fits only the no-load map: refused
    _trend_log(tmp_path / "no_ef.csv", {c: x for c, x in online.items() if c != "UF"} | {"IF": np.full(n, 0.8)})
    (tmp_path / "noload_if.yaml").write_text(NO_LOAD_MAP.replace("  v_f: {name: UF, unit: pu}\n", "") + extra[:29])
    maps = [load_channel_map(tmp_path / "noload_if.yaml"), load_channel_map(tmp_path / "online.yaml")]
    with pytest.raises(ChannelMapError, match=r"no_ef.csv: holds 'P', which .*online.yaml maps as p_e, but fits only"):
        import_pmu_csv([tmp_path / "no_ef.csv"], maps)


def _no_load_pair(tmp_path, names=("noload",)) -> None:
    n = 800
    for name in names:
        _trend_log(tmp_path / f"{name}.csv", {"UG": np.full(n, 1.0), "UF": np.full(n, 0.37)})


def test_a_map_entry_given_twice_or_naming_no_file_is_refused(tmp_path) -> None:
    """A map naming one scenario twice kept the second entry (the first's kind and regulator lost);
    an entry naming a file that is not there (step_O for step_0) was ignored; both silently."""
    _no_load_pair(tmp_path, ("step_0", "0412"))
    files = [tmp_path / "step_0.csv", tmp_path / "0412.csv"]
    (tmp_path / "twice.yaml").write_text(
        NO_LOAD_MAP + "scenarios:\n  step_0: {kind: field_step, regulator: manual}\n  step_0: {kind: unknown}\n"
    )
    with pytest.raises(
        ChannelMapError, match=r"twice\.yaml: line 9: the key 'step_0' is given twice \(first on line 8\)"
    ):
        load_channel_map(tmp_path / "twice.yaml")
    (tmp_path / "twice.json").write_text(
        '{"machine": {"mva": 30, "kv": 10.5}, "channels": {"v_t": {"name": "UG", "unit": "pu"}, "v_t": "UF"}}'
    )
    with pytest.raises(ChannelMapError, match=r"twice\.json: the key 'v_t' is given twice in one object"):
        load_channel_map(tmp_path / "twice.json")
    (tmp_path / "miss.yaml").write_text(NO_LOAD_MAP + "scenarios:\n  step_O: {kind: field_step}\n")
    with pytest.raises(ChannelMapError, match=r"miss\.yaml: scenarios\.step_O names no recording: .*\(close: step_0\)"):
        import_pmu_csv(files, load_channel_map(tmp_path / "miss.yaml"))
    # an entry for a file beside the ones read (a folder's map, some of its files imported) is no error;
    # a file named 0412 takes its entry (YAML 1.1 would read the key as the octal 266)
    (tmp_path / "ok.yaml").write_text(
        NO_LOAD_MAP + "scenarios:\n  step_0: {kind: unknown}\n  0412: {kind: field_step}\n"
    )
    rec = import_pmu_csv(files[1:], load_channel_map(tmp_path / "ok.yaml"))
    assert [(s.name, s.kind) for s in rec.scenarios] == [("0412", "field_step")]


def test_a_column_mapped_twice_or_named_twice_in_the_header_is_refused(tmp_path) -> None:
    """One column given for both v_t and v_f imported and identified (SEXS named on E_fd = V_t); a
    header naming a column twice had its second copy read and the first dropped, unlisted."""
    _no_load_pair(tmp_path)
    (tmp_path / "both.yaml").write_text(NO_LOAD_MAP.replace("v_f: {name: UF", "v_f: {name: UG"))
    with pytest.raises(ChannelMapError, match=r"both\.yaml: the column 'UG' is mapped as v_t and v_f"):
        load_channel_map(tmp_path / "both.yaml")
    n = 800
    rows = ["Timestamp,UG,UF,UG"] + [f"{k * 0.005:.4f},1.0,0.37,0.5" for k in range(n)]
    (tmp_path / "dup.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "map.yaml").write_text(NO_LOAD_MAP)
    with pytest.raises(ChannelMapError, match=r"dup\.csv: names the channel 'UG' 2 times \(columns 2, 4\)"):
        import_pmu_csv([tmp_path / "dup.csv"], load_channel_map(tmp_path / "map.yaml"))


def test_a_line_to_line_voltage_mapped_as_phase_is_refused_naming_kv_ll(tmp_path) -> None:
    """V_t in kV line to line mapped as kV (phase to neutral) imported at 1.73 pu at no load, said
    only inside the calibration line; a build-up from standstill (V_t 0 first) warned of a divide by zero."""
    import warnings

    n = 800
    ug = np.concatenate((np.zeros(100), np.full(n - 100, 10.5)))  # kV line to line, from standstill
    _trend_log(tmp_path / "noload.csv", {"UG": ug, "UF": np.full(n, 0.37), "P": np.zeros(n), "Q": np.zeros(n)})
    online = ON_LINE_MAP.replace("v_t: {name: UG, unit: pu}", "v_t: {name: UG, unit: kV}")
    (tmp_path / "kv.yaml").write_text(online)
    with pytest.raises(
        ChannelMapError, match=r"noload\.csv: V_t reads 1\.732 pu .*mapped as phase to neutral \(give unit: kV_ll\)"
    ):
        import_pmu_csv([tmp_path / "noload.csv"], load_channel_map(tmp_path / "kv.yaml"))
    (tmp_path / "kv_ll.yaml").write_text(online.replace("unit: kV}", "unit: kV_ll}"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy warning reaches the user
        rec = import_pmu_csv([tmp_path / "noload.csv"], load_channel_map(tmp_path / "kv_ll.yaml"))
    assert np.nanmax(rec.streams["pt_ct"].channels["v_t"]) == pytest.approx(1.0, abs=1e-6)


def test_an_endless_line_in_a_pmu_export_is_a_one_line_error(tmp_path) -> None:
    """A 300 KB field reached the user as ``_csv.Error: field larger than field limit``."""
    from phid_ros.errors import CsvImportError

    (tmp_path / "map.yaml").write_text(NO_LOAD_MAP)
    cmap = load_channel_map(tmp_path / "map.yaml")
    (tmp_path / "head.csv").write_text("Timestamp,UG" + "x" * (100 << 10) + "\n0,1\n")
    with pytest.raises(CsvImportError, match=r"head\.csv: the first line runs past 64 KB without ending"):
        import_pmu_csv([tmp_path / "head.csv"], cmap)
    (tmp_path / "body.csv").write_text("Timestamp,UG,UF\n0.000,1.0,0.37\n0.005," + "1" * (300 << 10) + ",0.37\n")
    with pytest.raises(
        PmuImportError, match=r"body\.csv: line 3: field larger than field limit .*\(an endless line\?\)"
    ):
        import_pmu_csv([tmp_path / "body.csv"], cmap)


def test_a_polled_log_is_read_on_its_own_stamps_and_a_real_gap_is_still_refused(tmp_path) -> None:
    """A laptop polling a controller over Telnet writes rows 0.12-0.69 s apart (median 0.15 s):
    every such log was refused as "reports missing". Now it is read on its stamps onto a grid at
    its median, the rule for a gap said; the interpolation's reach and a held channel are said;
    an interval of 2 s (13 x the median) is still missing reports."""
    rng = np.random.default_rng(4)
    dt = 0.15 + 0.03 * rng.standard_normal(600).clip(-1, 1)
    dt[::97] = 0.62  # the laptop's pauses
    t = np.concatenate(([0.0], np.cumsum(dt)))
    ug = 1.0 - 0.09 * (t > 30) * (1 - np.exp(-(t - 30).clip(0) / 4.0))
    ug_held = np.round(ug, 3)  # refreshed slower than polled: the same value row after row
    uf = 0.37 + 0.2 * (t > 30) * np.exp(-(t - 30).clip(0) / 4.0) + 1e-4 * rng.standard_normal(t.size)
    rows = ["Timestamp,UG,UF"] + [f"{a:.3f},{b:.6f},{c:.6f}" for a, b, c in zip(t, ug_held, uf)]
    (tmp_path / "polled.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "map.yaml").write_text(NO_LOAD_MAP)
    cmap = load_channel_map(tmp_path / "map.yaml")
    rec = import_pmu_csv([tmp_path / "polled.csv"], cmap)
    pt = rec.streams["pt_ct"]
    assert pt.period_ns == 150_000_000
    got = np.interp(t, (pt.t_ns - pt.t_ns[0]) / 1e9, pt.channels["v_t"])
    assert np.max(np.abs(got - ug_held)[t < t[-1] - 0.2]) < 0.002
    said = " ".join(rec.warnings)
    assert "polled.csv: a polled log (intervals" in said and "a gap would be one beyond 8 x the median" in said
    assert "of the line through its neighbours" in said
    assert "sampled and held by the source, refreshed slower than polled: v_t (UG:" in said
    assert "v_f (UF" not in said.split("sampled and held")[1]
    for k in range(300, len(rows)):  # a 2 s hole before the file's line 301
        a, rest = rows[k].split(",", 1)
        rows[k] = f"{float(a) + 2.0:.3f},{rest}"
    (tmp_path / "gap.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(
        PmuImportError, match=r"gap\.csv: reports missing at line 301: .*beyond 8 x its median 0\.150 s"
    ):
        import_pmu_csv([tmp_path / "gap.csv"], cmap)


def test_the_same_recording_under_a_second_name_is_refused_by_its_content(tmp_path) -> None:
    """A step file copied under a second name was counted twice: T'_d0 4.859 ± 0.149 s published
    where each file once gives 4.781 ± 0.172. Content, not names, decides."""
    _no_load_pair(tmp_path, ("step_0",))
    (tmp_path / "copy.csv").write_text((tmp_path / "step_0.csv").read_text())
    (tmp_path / "map.yaml").write_text(NO_LOAD_MAP)
    cmap = load_channel_map(tmp_path / "map.yaml")
    with pytest.raises(
        Exception, match=r"step_0\.csv: holds the same samples as .*copy\.csv: one recording given twice"
    ):
        import_pmu_csv([tmp_path / "copy.csv", tmp_path / "step_0.csv"], cmap)


def test_a_set_point_only_its_raise_and_lower_commands_record_is_integrated_at_the_ramp_rate(tmp_path) -> None:
    """Zakucac's controller logs its set-point's raise and lower commands (issue 71): where a log
    carries only those, v_ref is its start plus the map's ramp rate times the time a command was
    held. Lowered 3 s and raised 1 s at 0.005 pu/s from 0.98: 0.965, then 0.97. The rate is
    required (a pulse alone says nothing of how far it moves the set-point); a scenario's own start
    overrides the map's."""
    t = np.arange(0.0, 20.0, 0.01)
    lower = ((t >= 5.0) & (t < 8.0)).astype(float)
    raise_ = ((t >= 12.0) & (t < 13.0)).astype(float)
    rows = ["Timestamp,UG,UF,UP,DN"] + [
        f"{a:.3f},{1.0 - 0.01 * d:.6f},0.37,{u:g},{d:g}" for a, u, d in zip(t, raise_, lower)
    ]
    (tmp_path / "steps.csv").write_text("\n".join(rows) + "\n")
    pulses = "  v_ref_raise: {name: UP}\n  v_ref_lower: {name: DN}\n"
    (tmp_path / "no_rate.yaml").write_text(NO_LOAD_MAP + pulses)
    with pytest.raises(ChannelMapError, match=r"no_rate\.yaml: v_ref_raise and v_ref_lower mapped without the"):
        load_channel_map(tmp_path / "no_rate.yaml")
    text = NO_LOAD_MAP.replace("channels:", "set_point: {rate_pu_per_s: 0.005, start_pu: 1.0}\nchannels:") + pulses
    (tmp_path / "map.yaml").write_text(text + "scenarios:\n  steps: {set_point_start_pu: 0.98}\n")
    rec = import_pmu_csv([tmp_path / "steps.csv"], load_channel_map(tmp_path / "map.yaml"))
    sp = rec.streams["set_point"]
    at = (sp.t_ns - sp.t_ns[0]) / 1e9
    v_ref = sp.channels["v_ref"]
    assert v_ref[at < 5.0] == pytest.approx(0.98, abs=1e-12)
    assert v_ref[(at > 8.1) & (at < 12.0)] == pytest.approx(0.965, abs=1e-4)
    assert v_ref[at > 13.1] == pytest.approx(0.970, abs=1e-4)
    said = " ".join(rec.warnings)
    assert "steps.csv: v_ref from its raise/lower commands at 0.005 pu/s from 0.98 pu (0.9650-0.9800 pu)" in said
