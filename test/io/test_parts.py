"""A recording in parts: the same samples, the same replay, in bounded memory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from phid_ros.io.bags.recordings import read_recording
from phid_ros.io.msg_schemas import typestore
from phid_ros.io.overview import Overview
from phid_ros.io.parts import recording_parts
from phid_ros.stream.output_bag import OutputCollector
from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings
from phid_ros.stream.replay import replay
from phid_ros.stream.store import EventStore

BAGS = Path(__file__).resolve().parents[2] / "bags"


def _published(bag: Path, part_messages: int | None) -> list[tuple[int, str, bytes]]:
    """Every message a replay publishes, serialised, with the whole recording or in parts."""
    store = typestore()
    pipeline = MonitorPipeline(PipelineSettings())
    collector = OutputCollector(pipeline)
    if part_messages is None:
        replay(read_recording(bag), pipeline, on_outputs=collector, keep_arrays=False)
    else:
        replay(recording_parts(bag, part_messages), pipeline, on_outputs=collector, keep_arrays=False)
    pipeline.close()
    return [(t, topic, bytes(store.serialize_cdr(m, ty))) for t, topic, ty, m in collector.sorted()]


@pytest.mark.parametrize("bag", ["catalogue", "validation.mcap"])
def test_a_replay_in_parts_publishes_the_same_bytes(bag) -> None:
    whole = _published(BAGS / bag, None)
    assert len(whole) > 50
    # 7 messages a part: parts end inside the interleaved runs of a chunk unless cut at chunk ends
    for n in (7, 800):
        assert _published(BAGS / bag, n) == whole, n


def test_parts_hold_the_recording_in_file_order() -> None:
    whole = read_recording(BAGS / "catalogue")
    parts = recording_parts(BAGS / "catalogue", 500)
    assert parts.metadata == whole.metadata
    pieces = list(parts)
    assert len(pieces) > 10 and parts.fraction == pytest.approx(1.0, abs=1e-3) and not parts.warnings
    for name, s in whole.streams.items():
        for c, x in s.channels.items():
            got = np.concatenate([p.streams[name].channels[c] for p in pieces if name in p.streams])
            assert np.array_equal(got, x), (name, c)
        assert np.array_equal(np.concatenate([p.streams[name].t_ns for p in pieces if name in p.streams]), s.t_ns)
    assert [m.name for p in pieces for m in p.scenarios] == [m.name for m in whole.scenarios]


def test_the_overview_keeps_each_bins_extremes_in_bounded_size() -> None:
    rec = read_recording(BAGS / "catalogue")
    ov = Overview(max_bins=500)
    for part in recording_parts(BAGS / "catalogue", 300):
        ov.add(part)
    t, lo, hi = ov.envelope("v_t")
    v = rec.streams["pt_ct"].channels["v_t"]
    assert len(t) <= 500 and ov.span_ns() == rec.span_ns()
    assert lo.min() == v.min() and hi.max() == v.max()  # a fault's dip survives the decimation
    assert np.all(lo <= hi)


def test_a_memory_store_keeps_what_a_recalibration_reads() -> None:
    rec = read_recording(BAGS / "catalogue")
    pipeline = MonitorPipeline(PipelineSettings(auto_recalibrate=False))
    windows = replay(rec, pipeline).windows
    pipeline.close()
    full, kept = EventStore(), EventStore(retain_per_kind=2)
    for w in windows:
        full.add(w)
        kept.add(w)
    assert len(full) == len(windows) > len(kept)
    assert [w.event.event_id for w in kept.latest(n=2)] == [w.event.event_id for w in full.latest(n=2)]
    assert all(n <= 2 for n in kept.counts().values())


def _markers_last(src: Path, out: Path) -> Path:
    """``src`` rewritten with its scenario markers after every sample (any order is valid MCAP)."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    from phid_ros.io.topics import SCENARIO_TOPIC

    with src.open("rb") as fh:
        reader = make_reader(fh)
        messages = list(reader.iter_messages(log_time_order=False))
        metadata = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
    with out.open("wb") as fh:
        writer = Writer(fh)
        writer.start()
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, _ in messages:
            if schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id], dict(channel.metadata)
                )
        for name, data in metadata:
            writer.add_metadata(name, data)
        ordered = sorted(messages, key=lambda m: m[1].topic == SCENARIO_TOPIC)  # stable: markers last
        for _, channel, m in ordered:
            writer.add_message(channels[channel.id], m.log_time, m.data, m.publish_time, m.sequence)
        writer.finish()
    return out


def test_scenario_markers_written_after_their_samples_give_every_scenario(tmp_path) -> None:
    """Read in parts, a marker logged after its window's samples found nothing left of them:
    its scenario was dropped ("no disturbance found") though phid info listed it."""
    from phid_ros.stream.scenarios import scenarios_from_parts

    late = _markers_last(BAGS / "validation.mcap", tmp_path / "late.mcap")
    want, _ = scenarios_from_parts(recording_parts(BAGS / "validation.mcap", 50), "on time")
    got, problems = scenarios_from_parts(recording_parts(late, 50), "late")
    assert [s.name for s in got] == [s.name for s in want] == ["V1_power_step", "V2_voltage_dip", "V3_fault_150ms"]
    for a, b in zip(got, want):
        assert a.n == b.n and np.array_equal(a["v_t"], b["v_t"]) and a.kind == b.kind, a.name
    assert not any("skipped" in p for p in problems)


@pytest.mark.parametrize("bag", ["catalogue", "validation.mcap"])
def test_every_command_cuts_a_recording_as_identify_does(bag) -> None:
    """identify, validate, diagnose and the fleet share one path (api.cut_scenarios): part by part,
    the same windows as the whole recording gives, no samples kept beyond them, and its span."""
    from phid_ros.api import cut_scenarios, load_recording
    from phid_ros.stream.scenarios import scenarios_from_recording

    whole = load_recording(BAGS / bag)
    want, _ = scenarios_from_recording(whole, str(BAGS / bag))
    cut = cut_scenarios(BAGS / bag)
    assert [s.name for s in cut.scenarios] == [s.name for s in want]
    for a, b in zip(cut.scenarios, want):
        assert np.array_equal(a.frame.values, b.frame.values, equal_nan=True), a.name
    assert cut.recording.streams == {} and cut.recording.metadata == whole.metadata
    assert cut.span_ns == whole.span_ns() and cut.f_nominal_hz == whole.f_nominal_hz
