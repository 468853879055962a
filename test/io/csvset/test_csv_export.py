"""CSV export: a recording's scenarios out as the CSV set, and back in by the importer unchanged."""

from __future__ import annotations

import json

import numpy as np

from phid_ros.io.csvset.csv_export import write_csv_set
from phid_ros.io.csvset.csv_import import CSV_COLUMNS, import_csv_set
from phid_ros.io.topics import STREAMS


def test_export_then_import_gives_the_scenarios_back(tmp_path, short_recording, short_runs):
    manifest = write_csv_set(tmp_path / "set", short_recording)
    doc = json.loads(manifest.read_text())
    assert [e["kind"] for e in doc["scenarios"]] == [r.scenario.kind for r in short_runs]
    assert [e["generator_damping"] for e in doc["scenarios"]] == [r.scenario.generator_damping for r in short_runs]
    back = import_csv_set(manifest, strict=True)
    warnings = back.warnings
    assert warnings == []
    assert [s.name for s in back.scenarios] == [r.scenario.name for r in short_runs]
    header = (tmp_path / "set" / doc["scenarios"][0]["file"]).read_text().splitlines()[0]
    assert header.split(",") == list(CSV_COLUMNS)
    n = [r.n_analysis for r in short_runs]
    for spec in STREAMS:
        for c in spec.channels:
            got = back.streams[spec.name].channels[c]
            want = np.concatenate([r.measured[c][: r.n_analysis] for r in short_runs])
            assert len(got) == sum(n)
            # nine significant digits in the text: far below any sensor's resolution
            np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-12)


def test_the_spaces_between_csv_scenarios_are_not_reported_as_gaps(tmp_path, short_recording):
    from phid_ros.stream.scenarios import scenarios_from_recording

    rec = import_csv_set(write_csv_set(tmp_path / "set", short_recording))
    scenarios, problems = scenarios_from_recording(rec, "set")
    assert len(scenarios) == len(short_recording.scenarios)
    # the importer leaves 5 s between scenarios: gaps by design that touch no window
    assert not [p for p in problems if "gap(s)" in p], problems
