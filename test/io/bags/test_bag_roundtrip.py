"""Write -> read gives identical arrays, stamps, scenarios and metadata, for both formats."""

from __future__ import annotations

import numpy as np
import pytest

from phid_ros.io.bags.recordings import read_recording, topic_table, write_recording
from phid_ros.io.recording import Recording, ScenarioInfo, StreamSamples, block_bounds
from phid_ros.model.conventions import NS


def assert_same(a: Recording, b: Recording) -> None:
    assert set(a.streams) == set(b.streams)
    for name in a.streams:
        sa, sb = a.streams[name], b.streams[name]
        assert sa.period_ns == sb.period_ns
        assert np.array_equal(sa.t_ns, sb.t_ns)
        assert set(sa.channels) == set(sb.channels)
        for c in sa.channels:
            assert sa.channels[c].tobytes() == sb.channels[c].tobytes(), (name, c)
    # repr compares NaN magnitudes as equal, which == on the dataclasses does not
    assert [repr(x) for x in a.scenarios] == [repr(x) for x in b.scenarios]
    assert a.metadata == b.metadata


@pytest.mark.parametrize("suffix", ["", ".mcap"])
def test_simulated_recording_round_trips(tmp_path, short_recording, suffix):
    path = write_recording(tmp_path / f"bag{suffix}", short_recording)
    back = read_recording(path)
    assert_same(short_recording, back)
    assert len(back.scenarios) == 3 and back.scenarios[2].kind == "fault"
    assert back.scenarios[2].clearing_ns - back.scenarios[2].event_ns == 200_000_000


def _gappy_recording() -> Recording:
    """Irregular content: a gap, odd lengths, one-sample blocks, NaN and huge values."""
    period = 1_000_000
    t = np.concatenate([np.arange(0, 123) * period, 500 * period + np.arange(0, 7) * period]) + 10 * NS
    rng = np.random.default_rng(0)
    streams = {
        "pt_ct": StreamSamples(t, period, {c: rng.normal(size=t.size) for c in ("v_t", "i_d", "i_q", "p_e", "q_e")}),
        "encoder": StreamSamples(t[:1], period, {"omega": np.array([1.0]), "p_m": np.array([np.nan])}),
        "pmu": StreamSamples(t, period, {"theta_t": rng.normal(size=t.size), "delta": 1e300 * rng.normal(size=t.size)}),
        "excitation": StreamSamples(t[::1], period, {"v_f": np.full(t.size, 2.5)}),
    }
    sc = [ScenarioInfo("imported", "unknown", start_ns=int(t[0]), end_ns=int(t[-1]))]
    return Recording(streams=streams, scenarios=sc, metadata={"f_nominal_hz": "60.0"})


@pytest.mark.parametrize("suffix", ["", ".mcap"])
@pytest.mark.parametrize("block_size", [1, 50])
def test_gaps_single_samples_nan_and_extremes_round_trip(tmp_path, suffix, block_size):
    rec = _gappy_recording()
    back = read_recording(write_recording(tmp_path / f"g{suffix}", rec, block_size=block_size))
    assert_same(rec, back)
    assert back.f_nominal_hz == 60.0


def test_block_bounds_split_at_gaps_and_size():
    t = np.array([0, 1, 2, 3, 10, 11, 12], dtype=np.int64)
    assert block_bounds(t, 1, 2) == [(0, 2), (2, 4), (4, 6), (6, 7)]
    assert block_bounds(t, 1, 100) == [(0, 4), (4, 7)]


@pytest.mark.parametrize("suffix", ["", ".mcap"])
def test_topic_table_counts_messages(tmp_path, short_recording, suffix):
    path = write_recording(tmp_path / f"bag{suffix}", short_recording, block_size=100)
    table = {t: (ty, n) for t, ty, n in topic_table(path)}
    n_samples = len(short_recording.streams["pt_ct"])
    assert table["/generator/pt_ct"] == ("phid_msgs/msg/PtCtBlock", -(-n_samples // 100))
    assert table["/phid/scenarios"] == ("phid_msgs/msg/ScenarioMarker", 3)


def test_rosbag2_is_mcap_storage_with_zstd(tmp_path, short_recording):
    path = write_recording(tmp_path / "bag", short_recording)
    meta = (path / "metadata.yaml").read_text()
    assert "storage_identifier: mcap" in meta
    assert "version: 9" in meta
    head = (path / "bag.mcap").read_bytes()
    assert head.startswith(b"\x89MCAP0\r\n") and b"zstd" in head


def test_custom_data_reads_as_the_text_written(tmp_path, short_recording):
    """metadata.yaml's custom_data values as written, unquoted ones included: no YAML 1.1 guess
    turns ``yes`` into True or ``1:30`` into 90; an empty custom_data is no metadata."""
    path = write_recording(tmp_path / "bag", short_recording)
    meta = path / "metadata.yaml"
    text = meta.read_text()
    head, tail = text.split("  custom_data:\n", 1)
    meta.write_text(head + "  custom_data:\n    phid.flag: yes\n    phid.clock: 1:30\n    phid.rate: 0.50\n" + tail)
    got = read_recording(path).metadata
    assert (got["flag"], got["clock"], got["rate"]) == ("yes", "1:30", "0.50")
    lines = [ln for ln in text.splitlines() if not ln.startswith("    phid.")]
    meta.write_text("\n".join(ln if ln != "  custom_data:" else "  custom_data: null" for ln in lines) + "\n")
    assert read_recording(path).metadata == {}


@pytest.mark.parametrize("suffix", ["", ".mcap"])
def test_fast_reader_equals_the_library_readers(tmp_path, short_recording, suffix):
    from phid_ros.io.bags.mcap_file import read_mcap_reference
    from phid_ros.io.bags.rosbag2 import read_rosbag2_reference

    path = write_recording(tmp_path / f"bag{suffix}", short_recording, block_size=33)
    reference = read_mcap_reference(path) if suffix else read_rosbag2_reference(path)
    assert_same(reference, read_recording(path))
    assert_same(short_recording, reference)


def test_fast_mcap_walker_refuses_what_it_does_not_understand(tmp_path):
    from phid_ros.io.bags.mcap_raw import McapFormatError, iter_messages

    p = tmp_path / "x.mcap"
    p.write_bytes(b"not an mcap at all")
    with pytest.raises(McapFormatError, match="bad magic"):
        list(iter_messages(p))


def test_a_split_bag_reads_as_the_library_reader_reads_it_message_order_included(tmp_path, short_recording):
    """The fast reader numbers messages across a bag's files as the rosbags reader does: the
    replay feeds messages in that order (a clock that jumps between files stays a jump)."""
    import shutil

    from ruamel.yaml import YAML

    from phid_ros.io.bags.rosbag2 import read_rosbag2_reference

    one = write_recording(tmp_path / "one", short_recording, block_size=33)
    split = tmp_path / "split"
    split.mkdir()
    for name in ("a.mcap", "b.mcap"):
        shutil.copy(one / "one.mcap", split / name)
    meta = YAML(typ="safe").load((one / "metadata.yaml").read_text())
    info = meta["rosbag2_bagfile_information"]
    info["files"] = [dict(info["files"][0], path=n) for n in ("a.mcap", "b.mcap")]
    info["relative_file_paths"] = ["a.mcap", "b.mcap"]
    info["message_count"] *= 2
    for t in info["topics_with_message_count"]:
        t["message_count"] *= 2
    with (split / "metadata.yaml").open("w") as f:
        YAML().dump(meta, f)
    fast, reference = read_recording(split), read_rosbag2_reference(split)
    assert_same(reference, fast)
    n = len(short_recording.streams["pt_ct"])
    for name, s in fast.streams.items():
        r = reference.streams[name]
        assert len(s.t_ns) == 2 * n
        assert np.array_equal(s.msg_seq, r.msg_seq) and np.array_equal(s.msg_offsets, r.msg_offsets)
        assert np.all(np.diff(s.msg_seq) > 0)  # the second file's messages after the first's
