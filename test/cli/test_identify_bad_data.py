"""identify sees a recording as replay does: holes stay holes, conflicting duplicates are dropped and
counted, and a signal in kV or MW is refused with the unit it looks like."""

from __future__ import annotations

import dataclasses
import json

import pytest

from phid_ros.cli.main import main
from phid_ros.io.bags.recordings import write_messages, write_recording
from phid_ros.io.recording import Recording, StreamSamples, recording_messages


def _identify(path, tmp_path, capsys):
    out = tmp_path / "r.json"
    code = main(["identify", str(path), "--json", str(out), "--no-baseline"])
    captured = capsys.readouterr()
    return code, (json.loads(out.read_text()) if out.exists() else None), captured


def test_a_hole_in_every_stream_after_an_event_is_not_spliced(tmp_path, short_recording, capsys):
    fault = next(s for s in short_recording.scenarios if s.kind == "fault")
    cut = (fault.event_ns + 300_000_000, fault.event_ns + 800_000_000)  # 0.5 s, just after clearing
    streams = {}
    for name, s in short_recording.streams.items():
        keep = (s.t_ns < cut[0]) | (s.t_ns >= cut[1])
        streams[name] = StreamSamples(s.t_ns[keep], s.period_ns, {c: v[keep] for c, v in s.channels.items()})
    bag = write_recording(
        tmp_path / "hole.mcap", Recording(streams, short_recording.scenarios, short_recording.metadata)
    )
    code, doc, cap = _identify(bag, tmp_path, capsys)
    assert code == 0
    skipped = [p for p in doc["problems"] if f"skipped scenario {fault.name}" in p]
    assert skipped and "NaN" in skipped[0]
    assert fault.name not in [e["name"] for e in doc["events"]]
    assert any("pt_ct: 1 gap(s)" in p for p in doc["problems"])


def test_conflicting_duplicate_encoder_messages_are_dropped_and_counted(tmp_path, short_recording, capsys):
    clean = write_recording(tmp_path / "clean.mcap", short_recording)
    _, ref, _ = _identify(clean, tmp_path, capsys)
    msgs = []
    k = n_dup = 0
    windows = [(m.start_ns, m.end_ns) for m in short_recording.scenarios]
    for log, topic, typ, msg in recording_messages(short_recording):
        msgs.append((log, topic, typ, msg))
        if topic.endswith("/encoder"):
            k += 1
            if k % 10 == 0:  # every 10th message again, with another mechanical power
                msgs.append((log, topic, typ, dataclasses.replace(msg, p_m=msg.p_m + 0.05)))
                # counted where they matter: the samples (1 ms apart, the last at ``log``) in the scenarios' windows
                first = log - 99_000_000
                n_dup += sum(max(0, (min(b, log) - max(a, first)) // 1_000_000 + 1) for a, b in windows)
    dup = tmp_path / "dup.mcap"
    write_messages(dup, msgs, metadata=short_recording.metadata)
    code, doc, cap = _identify(dup, tmp_path, capsys)
    assert code == 0
    assert 0 < n_dup < (k // 10) * 100
    assert any(f"stream encoder: {n_dup} samples dropped: duplicate stamps" in p for p in doc["problems"])
    for name, value in ref["parameters"].items():  # the first value of each stamp kept: the same answer
        assert doc["parameters"][name] == pytest.approx(value, rel=1e-12, abs=1e-15), name


@pytest.mark.parametrize(
    "channel, factor, unit",
    [("v_t", 20.0, "kV"), ("p_e", 1000.0, "MW"), ("omega", 50.0, "Hz")],
)
def test_a_channel_in_physical_units_is_refused_with_its_likely_unit(
    tmp_path, short_recording, capsys, channel, factor, unit
):
    streams = {
        name: StreamSamples(
            s.t_ns, s.period_ns, {c: v * (factor if c == channel else 1.0) for c, v in s.channels.items()}
        )
        for name, s in short_recording.streams.items()
    }
    bag = write_recording(
        tmp_path / "units.mcap", Recording(streams, short_recording.scenarios, short_recording.metadata)
    )
    code, doc, cap = _identify(bag, tmp_path, capsys)
    assert code == 2 and doc is None
    assert f"channel {channel}: 100 % of samples outside the per-unit range" in cap.err
    assert f"looks like {unit}" in cap.err and str(bag) in cap.err


def test_import_csv_refuses_a_kv_column(tmp_path, catalogue_runs, capsys):
    from test.io.csvset.test_csv_import import write_set

    def kv(k, lines):
        header = lines[0].split(",")
        j = header.index("v_t")
        out = [lines[0]]
        for line in lines[1:]:
            f = line.split(",")
            f[j] = repr(float(f[j]) * 20.0)
            out.append(",".join(f))
        return out

    manifest = write_set(tmp_path, catalogue_runs[:1], mutate=kv)
    assert main(["import-csv", str(manifest), "--out", str(tmp_path / "b.mcap")]) == 2
    err = capsys.readouterr().err
    assert "s0.csv: channel v_t" in err and "looks like kV" in err
    assert not (tmp_path / "b.mcap").exists()


@pytest.mark.parametrize("name", ["../outside.csv", "/etc/passwd"])
def test_manifest_paths_stay_inside_its_folder(tmp_path, catalogue_runs, capsys, name):
    from test.io.csvset.test_csv_import import write_set

    folder = tmp_path / "set"
    folder.mkdir()
    manifest = write_set(folder, catalogue_runs[:1])
    (tmp_path / "outside.csv").write_text((folder / "s0.csv").read_text())
    doc = json.loads(manifest.read_text())
    doc["scenarios"][0]["file"] = name
    manifest.write_text(json.dumps(doc))
    assert main(["identify", str(manifest)]) == 2
    assert "outside the manifest's folder" in capsys.readouterr().err


def test_the_same_csv_listed_twice_counts_once(tmp_path, catalogue_runs, capsys):
    from test.io.csvset.test_csv_import import write_set

    runs = [r for r in catalogue_runs if r.scenario.name[:3] in ("S04", "S10", "S15")]
    manifest = write_set(tmp_path, runs)
    once = tmp_path / "once.json"
    assert main(["identify", str(manifest), "--json", str(once), "--no-baseline"]) == 0
    doc = json.loads(manifest.read_text())
    doc["scenarios"].append(dict(doc["scenarios"][0]))
    twice_manifest = tmp_path / "twice_manifest.json"
    twice_manifest.write_text(json.dumps(doc))
    twice = tmp_path / "twice.json"
    assert main(["identify", str(twice_manifest), "--json", str(twice), "--no-baseline"]) == 0
    a, b = json.loads(once.read_text()), json.loads(twice.read_text())
    assert any("the same data as scenario s0" in p for p in b["problems"])
    assert a["uncertainty"] == b["uncertainty"] and a["parameters"] == b["parameters"]


def test_nothing_to_identify_is_an_error_not_a_json_of_nulls(tmp_path, catalogue_runs, capsys):
    from test.io.csvset.test_csv_import import write_set

    runs = [r for r in catalogue_runs if r.scenario.role == "validate"]
    manifest = write_set(tmp_path, runs)
    out = tmp_path / "r.json"
    assert main(["identify", str(manifest), "--json", str(out)]) == 2
    assert "nothing to identify from" in capsys.readouterr().err and not out.exists()
