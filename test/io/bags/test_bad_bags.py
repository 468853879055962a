"""Every bad bag gives a BagError naming the file and the problem."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.enums import StoragePlugin
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from phid_ros.errors import BagError
from phid_ros.io.bags.recordings import read_recording, write_recording
from phid_ros.io.recording import Recording

BAGS = Path(__file__).resolve().parents[3] / "bags"


def test_missing_path(tmp_path):
    with pytest.raises(BagError, match="nope.*no such"):
        read_recording(tmp_path / "nope")


def test_folder_without_metadata(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(BagError, match="metadata.yaml missing"):
        read_recording(tmp_path / "empty")


def test_not_a_bag_file(tmp_path):
    p = tmp_path / "data.txt"
    p.write_text("hello")
    with pytest.raises(BagError, match="not a rosbag2 folder or .mcap"):
        read_recording(p)


def test_truncated_mcap_with_nothing_whole_before_the_cut(tmp_path, short_recording):
    path = write_recording(tmp_path / "r.mcap", short_recording)  # one chunk: a cut inside it leaves nothing
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(BagError, match=r"r\.mcap: truncated file: it ends after \d+ bytes"):
        read_recording(path)


def test_truncated_rosbag2_with_nothing_whole_before_the_cut(tmp_path, short_recording):
    path = write_recording(tmp_path / "bag", short_recording)
    inner = path / "bag.mcap"
    inner.write_bytes(inner.read_bytes()[: inner.stat().st_size // 2])
    with pytest.raises(BagError, match="bag.mcap: truncated file"):
        read_recording(path)


def _cut_after_chunks(data: bytes, fraction: float) -> bytes:
    import struct

    from phid_ros.io.bags.mcap_raw import MAGIC

    pos, ends = len(MAGIC), []
    while pos < len(data):
        op, length = struct.unpack_from("<BQ", data, pos)
        pos += 9 + length
        if op == 0x06:
            ends.append(pos)
        if op == 0x0F:
            break
    return data[: ends[int(len(ends) * fraction)]]


@pytest.mark.parametrize("form", ["mcap", "rosbag2"])
def test_a_recording_cut_at_a_chunk_boundary_is_read_with_a_warning_saying_how_much(tmp_path, form):
    """The bug: 50 of 80 s read as if complete, exit 0. Now the reader says it is truncated, and how much."""
    import shutil

    from phid_ros.io.bags.recordings import read_recording as read

    src = BAGS / "catalogue"
    data = _cut_after_chunks((src / "catalogue.mcap").read_bytes(), 0.6)
    if form == "mcap":
        path = tmp_path / "cut.mcap"
        path.write_bytes(data)
    else:
        path = tmp_path / "cut"
        shutil.copytree(src, path)
        (path / "catalogue.mcap").write_bytes(data)
    rec = read(path)
    [warning] = rec.warnings
    assert "truncated file: it ends after" in warning and "without its end-of-data record" in warning
    n = len(rec.streams["pt_ct"])
    assert 0 < n < 660_000 and f"pt_ct {n} samples ({(n - 1) / 1000:.1f} s)" in warning


def test_the_commands_warn_on_stderr_about_a_cut_recording(tmp_path, capsys):
    from phid_ros.cli.main import main

    path = tmp_path / "cut.mcap"
    path.write_bytes(_cut_after_chunks((BAGS / "catalogue" / "catalogue.mcap").read_bytes(), 0.6))
    assert main(["info", str(path)]) == 0
    cap = capsys.readouterr()
    assert cap.err.count("phid: warning:") == 1 and "truncated file" in cap.err and "truncated" not in cap.out


def test_corrupt_bytes_in_mcap(tmp_path, short_recording):
    path = write_recording(tmp_path / "c.mcap", short_recording)
    data = bytearray(path.read_bytes())
    mid = len(data) // 2
    data[mid : mid + 64] = b"\xff" * 64
    path.write_bytes(bytes(data))
    with pytest.raises(BagError, match=r"c\.mcap"):
        read_recording(path)


def _foreign_bag(path, topic: str, msgtype: str, msgdef: str | None = None):
    store = get_typestore(Stores.ROS2_JAZZY)
    if msgdef:
        store.register(get_types_from_msg(msgdef, msgtype))
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(topic, msgtype, typestore=store)
        if msgtype == "std_msgs/msg/String":
            msg = store.types[msgtype](data="x")
        else:
            msg = store.types[msgtype](value=1.0)
        writer.write(conn, 1, store.serialize_cdr(msg, msgtype))


def test_bag_without_the_expected_topics(tmp_path):
    _foreign_bag(tmp_path / "other", "/chatter", "std_msgs/msg/String")
    with pytest.raises(BagError, match=r"none of the phid sensor topics found \(topics present: /chatter\)"):
        read_recording(tmp_path / "other")


def test_wrong_type_on_a_sensor_topic(tmp_path):
    _foreign_bag(tmp_path / "wrong", "/generator/pt_ct", "std_msgs/msg/String")
    with pytest.raises(
        BagError, match="/generator/pt_ct has type std_msgs/msg/String, expected phid_msgs/msg/PtCtBlock"
    ):
        read_recording(tmp_path / "wrong")


def test_vendor_message_type_on_a_sensor_topic(tmp_path):
    _foreign_bag(tmp_path / "unknown", "/generator/pmu", "vendor_msgs/msg/Angle", "float64 value")
    with pytest.raises(
        BagError, match="/generator/pmu has type vendor_msgs/msg/Angle, expected phid_msgs/msg/PmuBlock"
    ):
        read_recording(tmp_path / "unknown")


def test_some_streams_missing(tmp_path, short_recording):
    partial = Recording(
        streams={k: v for k, v in short_recording.streams.items() if k != "pmu"},
        scenarios=short_recording.scenarios,
        metadata=short_recording.metadata,
    )
    path = write_recording(tmp_path / "partial.mcap", partial)
    with pytest.raises(BagError, match=r"partial\.mcap: no messages on the sensor stream\(s\) \['pmu'\]"):
        read_recording(path)


def test_existing_output_is_not_overwritten(tmp_path, short_recording):
    path = write_recording(tmp_path / "keep.mcap", short_recording)
    before = path.read_bytes()
    with pytest.raises(BagError, match="already exists"):
        write_recording(path, short_recording)
    assert path.read_bytes() == before
    folder = write_recording(tmp_path / "keepdir", short_recording)
    with pytest.raises(BagError, match="already exists"):
        write_recording(folder, short_recording)
    shutil.rmtree(folder)


@pytest.mark.parametrize("name", ["broken.mcap", "broken"])
def test_a_failed_write_leaves_nothing_behind(tmp_path, name):
    from phid_ros.io.bags.recordings import write_messages
    from phid_ros.io.recording import recording_messages

    def messages():
        yield from recording_messages(_small())[:3]
        raise RuntimeError("producer failed")

    with pytest.raises(RuntimeError, match="producer failed"):
        write_messages(tmp_path / name, messages())
    assert not (tmp_path / name).exists()


def _small():
    import numpy as np

    from phid_ros.io.recording import Recording, StreamSamples

    t = np.arange(10, dtype=np.int64) * 1_000_000
    return Recording(streams={"pmu": StreamSamples(t, 1_000_000, {"theta_t": np.zeros(10), "delta": np.ones(10)})})


def test_a_pmu_clock_an_hour_off_is_named_not_a_recording_without_events(tmp_path, short_recording):
    """PMU stamps in UTC beside PT/CT in local time: 'no disturbance found', 0 events, exit 0
    before. The streams meet no other data; the reader names the offset instead."""
    import copy

    from phid_ros.api import load_recording, write_output
    from phid_ros.errors import PhidError
    from phid_ros.model.conventions import NS

    rec = copy.deepcopy(short_recording)
    rec.streams["pmu"].t_ns = rec.streams["pmu"].t_ns + 3600 * NS
    out = tmp_path / "offset.mcap"
    write_output(out, rec, 100)
    with pytest.raises(
        PhidError,
        match=r"the pmu stream's stamps do not overlap the pt_ct stream's: they start "
        r"\+3600\.0 s from them \(a whole number of hours: UTC against local time\?\)",
    ):
        load_recording(out)


@pytest.mark.parametrize("offset_s, named", [(2.0, True), (-0.8, True), (0.05, False)])
def test_a_pmu_clock_seconds_off_is_found_by_the_swings_a_latency_is_left_to_the_diagnosis(
    short_recording, offset_s, named
):
    """dδ/dt = ω_s (ω − 1) at every instant: cross-correlated, the PMU's rate and the encoder's
    speed give the offset (2 s off flagged parameters without a hint before). 50 ms is a
    sensor latency, which the diagnosis fits (sensor_delay); it is not refused."""
    import copy

    from phid_ros.io.field.clock_check import clock_problems, pmu_lag_s
    from phid_ros.model.conventions import NS

    rec = copy.deepcopy(short_recording)
    rec.streams["pmu"].t_ns = rec.streams["pmu"].t_ns + int(offset_s * NS)
    assert pmu_lag_s(rec, 50.0) == pytest.approx(offset_s, abs=0.011)
    problems = clock_problems(rec)
    if named:
        assert problems == [
            f"the pmu stream stamps the rotor's swings {abs(offset_s):.2f} s {'after' if offset_s > 0 else 'before'} "
            "the encoder does (dδ/dt against ω, cross-correlated): a clock offset; correct the clock of one of them"
        ]
    else:
        assert problems == []
    assert clock_problems(short_recording) == []


@pytest.mark.parametrize("stream", ["pt_ct", "encoder"])
def test_a_pt_ct_or_encoder_clock_seconds_off_is_found_by_the_swing_equation(short_recording, stream):
    """P_e's swings are the speed's rate's, turned over (2H dω/dt = P_m − P_e − D(ω − 1)):
    cross-correlated they give a PT/CT clock's offset; an encoder off both others is named as such."""
    import copy

    from phid_ros.io.field.clock_check import clock_problems, pt_ct_lag_s
    from phid_ros.model.conventions import NS

    rec = copy.deepcopy(short_recording)
    rec.streams[stream].t_ns = rec.streams[stream].t_ns + int(1.5 * NS)
    if stream == "pt_ct":
        assert pt_ct_lag_s(rec) == pytest.approx(1.5, abs=0.011)
        assert clock_problems(rec) == [
            "the pt_ct stream stamps the rotor's swings 1.50 s after the encoder does (P_e against dω/dt, "
            "cross-correlated): a clock offset; correct the clock of one of them"
        ]
    else:
        assert clock_problems(rec) == [
            "the encoder stream stamps the rotor's swings 1.50 s after both the pmu and the pt_ct streams do "
            "(cross-correlated): a clock offset of the encoder; correct it"
        ]
    assert pt_ct_lag_s(short_recording) == pytest.approx(0.0, abs=0.011)


def test_a_chunk_declaring_gigabytes_is_refused_not_allocated():
    """A few bytes of zstd can declare, and inflate to, gigabytes: refused by the declared size."""
    import zstandard

    from phid_ros.io.bags.mcap_raw import MAX_CHUNK_BYTES, McapFormatError, _decompress

    packed = zstandard.ZstdCompressor().compress(b"\0" * 4096)
    assert _decompress("zstd", packed, 4096) == b"\0" * 4096
    with pytest.raises(McapFormatError, match=r"a chunk declares \d+ bytes uncompressed, more than the 1024 MB"):
        _decompress("zstd", packed, MAX_CHUNK_BYTES + 1)
    import lz4.frame

    with pytest.raises(McapFormatError, match=r"a chunk inflates beyond the 100 bytes it declares"):
        _decompress("lz4", lz4.frame.compress(b"\0" * 4096), 100)


def test_a_bag_metadata_with_yaml_aliases_is_refused(tmp_path, short_recording):
    from phid_ros.io.bags.rosbag2 import bag_metadata

    bag = tmp_path / "bag"
    write_recording(bag, short_recording)
    meta = bag / "metadata.yaml"
    meta.write_text(meta.read_text() + "\nx: &a [1, 2]\ny: [*a, *a]\n")
    with pytest.raises(BagError, match=r"metadata\.yaml: holds YAML aliases, which rosbag2 never writes"):
        bag_metadata(bag)


def test_a_json_nested_too_deeply_is_one_line(tmp_path):
    from phid_ros.errors import ResultsError
    from phid_ros.io.files.results import read_json

    deep = tmp_path / "r.json"
    deep.write_text('{"a": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(ResultsError, match=r"r\.json: nested too deeply"):
        read_json(deep)
