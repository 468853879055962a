from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

from phid_ros.errors import CsvImportError
from phid_ros.io.bags.recordings import read_recording, write_recording
from phid_ros.io.csvset.csv_import import CSV_COLUMNS, import_csv_set
from phid_ros.model.conventions import NS


def write_set(folder: Path, runs, *, gz: bool = False, extra: dict | None = None, mutate=None) -> Path:
    """A CSV scenario set in the README's contract format from simulated runs."""
    entries = []
    for k, run in enumerate(runs):
        n = run.n_analysis  # a CSV export holds the scenario, not the simulator's restore period
        cols = {"t": run.t[:n], **{c: v[:n] for c, v in run.measured.items()}}
        if extra:
            cols.update({name: np.full(n, v) for name, v in extra.items()})
        header = list(cols)
        rows = np.column_stack([cols[h] for h in header])
        lines = [",".join(header)] + [",".join(repr(float(v)) for v in row) for row in rows]
        if mutate:
            lines = mutate(k, lines)
        name = f"s{k}.csv" + (".gz" if gz else "")
        text = "\n".join(lines) + "\n"
        if gz:
            with gzip.open(folder / name, "wt") as fh:
                fh.write(text)
        else:
            (folder / name).write_text(text)
        entries.append(
            {
                "file": name,
                "kind": run.scenario.kind,
                "role": run.scenario.role,
                "generator_damping": run.scenario.generator_damping,
            }
        )
    manifest = folder / "manifest.json"
    manifest.write_text(json.dumps({"f_nominal_hz": 50, "base_mva": 1000, "scenarios": entries}))
    return manifest


@pytest.mark.parametrize("gz", [False, True])
def test_import_keeps_every_value_and_places_scenarios_in_order(tmp_path, short_runs, gz):
    manifest = write_set(tmp_path, short_runs, gz=gz, extra={"id_ref": 0.0})
    rec = import_csv_set(manifest)
    warnings = rec.warnings
    assert len(warnings) == 3 and "ignored extra column(s) ['id_ref']" in warnings[0]
    n = short_runs[0].n_analysis
    for c, values in short_runs[0].measured.items():
        values = values[:n]
        stream = next(s for s in rec.streams.values() if c in s.channels)
        assert np.array_equal(stream.channels[c][:n], values)
    assert [s.kind for s in rec.scenarios] == ["torque_step", "voltage_step", "fault"]
    gaps = [b.start_ns - a.end_ns for a, b in zip(rec.scenarios, rec.scenarios[1:])]
    assert all(g == 5 * NS for g in gaps)
    assert rec.streams["pt_ct"].period_ns == 1_000_000
    # and it survives a bag round trip
    back = read_recording(write_recording(tmp_path / "imported.mcap", rec))
    assert np.array_equal(back.streams["pmu"].channels["delta"], rec.streams["pmu"].channels["delta"])


def _set_field(file_line: int, column: str, value: str):
    """Mutator: in the second CSV, put ``value`` into ``column`` on 1-based ``file_line``."""

    def mutate(k, lines):
        if k == 1:
            j = lines[0].split(",").index(column)
            fields = lines[file_line - 1].split(",")
            fields[j] = value
            lines[file_line - 1] = ",".join(fields)
        return lines

    return mutate


def _append_field(file_line: int):
    def mutate(k, lines):
        if k == 1:
            lines[file_line - 1] += ",1"
        return lines

    return mutate


@pytest.mark.parametrize(
    "mutate, message",
    [
        (
            lambda k, lines: [lines[0].replace("omega", "omegaa")] + lines[1:],
            r"s0\.csv: missing column\(s\) 'omega' \(found 'omegaa'\)",
        ),
        (
            lambda k, lines: [lines[0].replace(",q_e", "")] + [ln.rsplit(",", 1)[0] for ln in lines[1:]],
            r"s0\.csv: missing column\(s\) 'q_e'",
        ),
        (_set_field(11, "i_d", "nan"), r"s1\.csv: line 11, column 'i_d' is nan"),
        (_set_field(13, "v_t", "inf"), r"s1\.csv: line 13, column 'v_t' is inf"),
        (_set_field(21, "i_q", "abc"), r"s1\.csv: line 21, column 'i_q': not a number \('abc'\)"),
        (_append_field(31), r"s1\.csv: line 31 has 12 fields, header has 11"),
        (_set_field(41, "t", "0.0"), r"s1\.csv: time is not strictly increasing at line 41 \(t=0\.0 after 0\.038\)"),
    ],
)
def test_bad_csv_files_are_named_with_the_problem(tmp_path, short_runs, mutate, message):
    manifest = write_set(tmp_path, short_runs, mutate=mutate)
    with pytest.raises(CsvImportError, match=message):
        import_csv_set(manifest)


def test_strict_refuses_extra_columns(tmp_path, short_runs):
    manifest = write_set(tmp_path, short_runs[:1], extra={"speed_rpm": 3000.0})
    with pytest.raises(CsvImportError, match=r"s0\.csv: unknown column\(s\) \['speed_rpm'\]"):
        import_csv_set(manifest, strict=True)


def test_non_uniform_sampling_is_refused(tmp_path, short_runs):
    def mutate(k, lines):
        head, *rows = lines
        rows = [r for i, r in enumerate(rows) if i % 3 != 1]  # drop every third sample
        return [head, *rows]

    with pytest.raises(CsvImportError, match=r"non-uniform sampling"):
        import_csv_set(write_set(tmp_path, short_runs[:1], mutate=mutate))


@pytest.mark.parametrize(
    "manifest, message",
    [
        ({"scenarios": []}, "'scenarios' must be a non-empty list"),
        ({"scenarios": [{"kind": "fault"}]}, r"scenarios\[0\]: each scenario needs a 'file'"),
        ({"scenarios": [{"file": "a.csv", "kind": "storm"}]}, r"kind 'storm' not one of"),
        ({"scenarios": [{"file": "a.csv", "role": "train"}]}, r"role 'train' not one of"),
        ({"f_nominal_hz": -50, "scenarios": [{"file": "a.csv"}]}, "f_nominal_hz must be a positive number"),
        ({"scenarios": [{"file": "missing.csv"}]}, r"missing\.csv: no such CSV file"),
    ],
)
def test_bad_manifests(tmp_path, manifest, message):
    path = tmp_path / "manifest.json"
    path.write_text(json.dumps(manifest))
    with pytest.raises(CsvImportError, match=message):
        import_csv_set(path)


def test_manifest_not_json(tmp_path):
    path = tmp_path / "manifest.json"
    path.write_text("{oops")
    with pytest.raises(CsvImportError, match=r"manifest\.json: not valid JSON"):
        import_csv_set(path)


def test_required_columns_are_the_design_contract():
    assert CSV_COLUMNS == ("t", "v_t", "theta_t", "i_d", "i_q", "omega", "delta", "v_f", "p_m", "p_e", "q_e")


def test_a_spreadsheet_export_reads_as_the_plain_one(tmp_path):
    """A UTF-8 byte-order mark (the header read as '\\ufefft') and a decimal-comma locale's
    ';'-separated fields with 0,5 for 0.5 ("all 11 columns missing" before) read as the plain CSV."""
    from phid_ros.io.csvset.csv_import import CSV_COLUMNS, read_scenario_csv

    t = np.arange(5) * 1e-3
    rows = [[ti] + [0.5 + 0.01 * k for k in range(len(CSV_COLUMNS) - 1)] for ti in t]
    plain = tmp_path / "plain.csv"
    plain.write_text(",".join(CSV_COLUMNS) + "\n" + "\n".join(",".join(f"{v:.6g}" for v in r) for r in rows) + "\n")
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    euro = tmp_path / "euro.csv"
    euro.write_text(
        ";".join(CSV_COLUMNS) + "\n" + "\n".join(";".join(f"{v:.6g}".replace(".", ",") for v in r) for r in rows) + "\n"
    )
    want, _ = read_scenario_csv(plain)
    for path in (bom, euro):
        got, extra = read_scenario_csv(path)
        assert extra == [] and all(np.array_equal(got[c], want[c]) for c in CSV_COLUMNS), path


def test_a_decimal_comma_export_with_thousands_points_reads_whole_numbers(tmp_path):
    """A decimal-comma locale writes 802.637,5 for 802637.5: every ',' became '.' and the '.'
    stayed, so P was read 1000x small (X_d +81 % published as identified). Now the point groups
    thousands, and a point that cannot (1.5 beside 0,5) is refused by line and field."""
    from phid_ros.io.csvset.csv_import import CSV_COLUMNS, read_scenario_csv

    t = np.arange(5) * 1e-3
    rows = [[ti] + [802637.5 + k if k % 2 else 802637 + k for k in range(len(CSV_COLUMNS) - 1)] for ti in t]

    def grouped(v: float) -> str:  # 802.637,5 and 802.637 (a whole kW: no comma at all)
        return f"{v:,.{1 if v % 1 else 0}f}".replace(",", " ").replace(".", ",").replace(" ", ".")

    euro = tmp_path / "euro.csv"
    body = "\n".join(";".join([f"{r[0]:.6g}".replace(".", ","), *map(grouped, r[1:])]) for r in rows)
    euro.write_text(";".join(CSV_COLUMNS) + "\n" + body + "\n")
    got, _ = read_scenario_csv(euro)
    for k, c in enumerate(CSV_COLUMNS[1:]):
        assert got[c][0] == (802637.5 + k if k % 2 else 802637 + k), c
    assert got["t"][3] == pytest.approx(3e-3)
    lines = euro.read_text().splitlines()
    lines[3] = lines[3].replace("802.638,5", "1.5", 1)
    euro.write_text("\n".join(lines) + "\n")
    with pytest.raises(CsvImportError, match=r"euro\.csv: line 4, field \d+: '1\.5' has a point that does not group"):
        read_scenario_csv(euro)


def test_a_channel_nan_throughout_is_not_recorded_and_a_gap_in_one_is_refused(tmp_path):
    """phid writes a partial-channel import's CSV set with NaN for what the recorder lacked
    (a trend log has no i_d): its own output was refused ("column 'i_d' is nan"). A channel NaN in
    every row is read as not recorded; a channel with values and a NaN is refused as before."""
    from phid_ros.io.csvset.csv_import import CSV_COLUMNS, read_scenario_csv

    rows = [[k * 1e-3] + [0.5] * (len(CSV_COLUMNS) - 1) for k in range(5)]
    i_d = CSV_COLUMNS.index("i_d")
    for r in rows:
        r[i_d] = float("nan")
    path = tmp_path / "partial.csv"
    path.write_text(",".join(CSV_COLUMNS) + "\n" + "\n".join(",".join(f"{v:g}" for v in r) for r in rows) + "\n")
    got, _ = read_scenario_csv(path)
    assert np.isnan(got["i_d"]).all() and (got["v_t"] == 0.5).all()
    rows[2][i_d] = 0.1
    path.write_text(",".join(CSV_COLUMNS) + "\n" + "\n".join(",".join(f"{v:g}" for v in r) for r in rows) + "\n")
    with pytest.raises(CsvImportError, match=r"line 2, column 'i_d' is nan"):
        read_scenario_csv(path)


def test_a_compressed_csv_that_inflates_past_the_bound_is_refused(tmp_path, monkeypatch):
    """A 650 KB .csv.gz inflated without bound; now one line, before it is held."""
    from phid_ros.io.csvset import csv_import

    monkeypatch.setattr(csv_import, "MAX_SCENARIO_CSV_BYTES", 1000)
    path = tmp_path / "bomb.csv.gz"
    with gzip.open(path, "wt") as fh:
        fh.write(",".join(CSV_COLUMNS) + "\n" + "0,0,0,0,0,0,0,0,0,0,0\n" * 200)
    assert path.stat().st_size < 200
    with pytest.raises(CsvImportError, match=r"bomb\.csv\.gz: more than 0 MB of text in one scenario"):
        csv_import.read_scenario_csv(path)


def test_a_compressed_csv_of_blank_lines_or_an_endless_header_is_refused_within_bounded_memory(tmp_path):
    """0.65 MB of .csv.gz inflating to 640 MB of blank lines ran out of memory splitting them
    (14 GB, MemoryError); one endless header line reached the csv module ("field larger than field
    limit"). Both are one line now; the blank lines are counted, not split (a smaller bomb here)."""
    from phid_ros.io.csvset import csv_import

    path = tmp_path / "blank.csv.gz"
    with gzip.open(path, "wb", compresslevel=9) as fh:
        fh.write((",".join(CSV_COLUMNS) + "\n" + "0,0,0,0,0,0,0,0,0,0,0\n" * 2).encode())
        fh.write(b"\n" * (8 << 20))
    assert path.stat().st_size < 20_000
    with pytest.raises(CsvImportError, match=r"blank\.csv\.gz: 8388610 lines in 8 MB of text, most of them blank"):
        csv_import.read_scenario_csv(path)
    endless = tmp_path / "endless.csv"
    endless.write_text("t" + "x" * (200 << 10) + "\n0\n")
    with pytest.raises(CsvImportError, match=r"endless\.csv: the first line runs past 64 KB without ending"):
        csv_import.read_scenario_csv(endless)


def test_semicolon_fields_with_decimal_points_still_read(tmp_path):
    """';' between fields does not make the point a thousands mark: without a comma anywhere the
    points are decimal points (0.5;1.25 is 0.5 and 1.25, as before)."""
    from phid_ros.io.csvset.csv_import import CSV_COLUMNS, read_scenario_csv

    rows = [[k * 1e-3] + [0.5 + 0.25 * j for j in range(len(CSV_COLUMNS) - 1)] for k in range(5)]
    path = tmp_path / "points.csv"
    path.write_text(";".join(CSV_COLUMNS) + "\n" + "\n".join(";".join(f"{v:g}" for v in r) for r in rows) + "\n")
    got, _ = read_scenario_csv(path)
    assert got["v_t"][0] == 0.5 and got["q_e"][4] == 0.5 + 0.25 * (len(CSV_COLUMNS) - 2)


def test_a_manifest_s_regulator_is_checked(tmp_path) -> None:
    import json

    from phid_ros.io.csvset.csv_import import CsvImportError, import_csv_set

    rows = ["t,v_t,theta_t,i_d,i_q,omega,delta,v_f,p_m,p_e,q_e"]
    rows += [f"{k * 0.01:.2f},1,0,0.5,0.5,1,0.8,1.5,0.8,0.8,0.2" for k in range(300)]
    (tmp_path / "a.csv").write_text("\n".join(rows) + "\n")
    manifest = tmp_path / "manifest.json"
    manifest.write_text(json.dumps({"scenarios": [{"file": "a.csv", "kind": "field_step", "regulator": "hand"}]}))
    with pytest.raises(CsvImportError, match=r"regulator 'hand' not one of \('avr', 'avr\+pss', 'manual'\)"):
        import_csv_set(manifest)
    for regulator in ("manual", "avr+pss"):  # a manual test; the AVR with its stabiliser on
        entry = {"file": "a.csv", "kind": "field_step", "regulator": regulator}
        manifest.write_text(json.dumps({"scenarios": [entry]}))
        rec = import_csv_set(manifest)
        assert rec.scenarios[0].regulator == regulator
    # through a bag and back: the marker's description carries it
    from phid_ros.io.bags.recordings import read_recording, write_recording

    write_recording(tmp_path / "a.mcap", rec)
    assert read_recording(tmp_path / "a.mcap").scenarios[0].regulator == "avr+pss"


def test_the_field_bases_travel_in_the_manifest_and_a_bad_one_is_named(tmp_path, short_runs):
    from phid_ros.io.recording import FIELD_BASES_KEY, FieldBases, field_bases

    manifest = write_set(tmp_path, short_runs[:1])
    meta = json.loads(manifest.read_text())
    meta[FIELD_BASES_KEY] = FieldBases(74.0, 725.0).text()
    manifest.write_text(json.dumps(meta))
    rec = import_csv_set(manifest)
    got = field_bases(rec.metadata)
    assert got == FieldBases(74.0, 725.0) and got.ohms_per_unit == pytest.approx(74 / 725)
    assert field_bases({FIELD_BASES_KEY: "v_f=74.0 V"}) == FieldBases(74.0, None)
    for bad in ("v_f=74 A", "i_fd=-3 A", "v_f=74 V;base=3", 12):
        meta[FIELD_BASES_KEY] = bad
        manifest.write_text(json.dumps(meta))
        with pytest.raises(CsvImportError, match=r"manifest\.json: field_bases must read like 'v_f=74 V;i_fd=725 A'"):
            import_csv_set(manifest)
