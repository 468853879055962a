"""The vectorised block decoder agrees with the rosbags deserialiser, and falls back when it must."""

from __future__ import annotations

import numpy as np

from phid_ros.io.bags.cdr_blocks import block_layout, decode_group, stack_by_length
from phid_ros.io.msg_schemas import typestore
from phid_ros.io.recording import recording_from_messages, recording_from_raw, recording_messages


def _pt_ct(n: int, frame_id: str = "generator", sec: int = 5):
    store = typestore()
    hdr = store.types["std_msgs/msg/Header"](
        stamp=store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=9), frame_id=frame_id
    )
    rng = np.random.default_rng([n, sec])  # messages of one test differ by their stamps and their samples
    arrays = {c: rng.normal(size=n) for c in ("v_t", "i_d", "i_q", "p_e", "q_e")}
    msg = store.types["phid_msgs/msg/PtCtBlock"](header=hdr, sample_period=1e-3, **arrays)
    return bytes(store.serialize_cdr(msg, "phid_msgs/msg/PtCtBlock")), arrays


def test_layout_matches_serialised_size_for_many_shapes():
    for n in (0, 1, 2, 3, 50, 51):
        for frame in ("", "g", "generator", "abcdefgh"):
            raw, _ = _pt_ct(n, frame)
            assert block_layout(len(frame), 5, n).total == len(raw)


def test_group_decode_equals_reference():
    raws, arrays = zip(*(_pt_ct(7, sec=s) for s in range(4)))
    groups, positions = stack_by_length(list(raws), [10, 11, 12, 13])
    assert len(groups) == 1 and list(positions) == [10, 11, 12, 13]
    rows, idx = groups[0]
    assert list(idx) == [0, 1, 2, 3]
    dec = decode_group(rows, idx, None, 5)
    assert dec is not None
    assert dec.t0_ns.tolist() == decode_group(list(raws), idx, None, 5).t0_ns.tolist()  # type: ignore[union-attr]
    assert list(dec.t0_ns) == [s * 1_000_000_000 + 9 for s in range(4)]
    for j, c in enumerate(("v_t", "i_d", "i_q", "p_e", "q_e")):
        assert np.array_equal(dec.values[j], np.stack([a[c] for a in arrays]))


def test_unequal_arrays_fall_back_to_the_reference_and_are_refused():
    store = typestore()
    raw, _ = _pt_ct(4)
    msg = store.deserialize_cdr(raw, "phid_msgs/msg/PtCtBlock")
    msg.q_e = np.zeros(3)
    bad = bytes(store.serialize_cdr(msg, "phid_msgs/msg/PtCtBlock"))
    groups, _ = stack_by_length([bad], [0])
    assert decode_group(groups[0][0], groups[0][1], None, 5) is None  # not the block layout: the reference decodes it
    import pytest

    from phid_ros.errors import BagError

    items = [("/generator/pt_ct", "phid_msgs/msg/PtCtBlock", bad)]
    with pytest.raises(BagError, match=r"pt_ct message 0 has arrays of unequal length \[3, 4\]"):
        recording_from_raw(items, source="x.mcap", required=("pt_ct",))


def test_object_path_and_raw_path_build_the_same_recording(short_recording):
    store = typestore()
    msgs = recording_messages(short_recording, block_size=37)
    a = recording_from_messages(((t, ty, m) for _, t, ty, m in msgs), source="objects")
    b = recording_from_raw(((t, ty, bytes(store.serialize_cdr(m, ty))) for _, t, ty, m in msgs), source="raw")
    for name in a.streams:
        assert np.array_equal(a.streams[name].t_ns, b.streams[name].t_ns)
        for c in a.streams[name].channels:
            assert np.array_equal(a.streams[name].channels[c], b.streams[name].channels[c])
            assert np.array_equal(a.streams[name].channels[c], short_recording.streams[name].channels[c])


def test_stacking_orders_rows_by_position_whatever_order_single_messages_and_runs_come_in():
    """Rows are placed by their position in the file: runs (as the walk gives them, a chunk's cycle
    at a time) and single messages arrive out of file order, some backwards, some shuffled."""
    rng = np.random.default_rng(3)
    n = 40
    payload = [rng.bytes(16) for _ in range(n)]
    as_rows = np.frombuffer(b"".join(payload), dtype=np.uint8).reshape(n, 16)
    items = (
        [
            (as_rows[10:20], np.arange(110, 120)),  # a run
            (payload[3], 103),
            (as_rows[25:40], np.arange(125, 140)),  # another run
            (payload[2], 102),  # singles backwards
            (payload[1], 101),
            (as_rows[[20, 22, 21, 23, 24]], np.array([120, 122, 121, 123, 124])),  # consecutive, not rising
            (payload[0], 100),
        ]
        + [(payload[k], 100 + k) for k in range(4, 10)]
    )
    groups, positions = stack_by_length([p for p, _ in items], [w for _, w in items])
    assert positions.tolist() == list(range(100, 100 + n))
    # the ten single messages stacked into one part, each run kept as the array it came as
    assert [len(rows) for rows, _ in groups] == [10, 10, 15, 5]
    assert all(np.shares_memory(groups[i][0], as_rows) for i in (1, 2))
    placed = np.zeros((n, 16), dtype=np.uint8)
    for rows, idx in groups:
        placed[idx] = rows
    assert sorted(i for _, idx in groups for i in idx.tolist()) == list(range(n))
    assert placed.tobytes() == b"".join(payload)


def test_a_stream_assembled_from_runs_and_single_messages_in_any_order():
    """Runs copied by slices, single messages and a run not in rising order scattered: the stream
    is the messages' samples in file order."""
    raws = [_pt_ct(7, sec=s)[0] for s in range(12)]
    length = len(raws[0])
    rows = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(12, length)
    topic, msgtype = "/generator/pt_ct", "phid_msgs/msg/PtCtBlock"
    items = [
        (topic, msgtype, rows[4:8], np.arange(4, 8)),
        (topic, msgtype, raws[1], 1),
        (topic, msgtype, rows[[9, 8, 10]], np.array([9, 8, 10])),
        (topic, msgtype, raws[0], 0),
        (topic, msgtype, rows[2:4], np.arange(2, 4)),
        (topic, msgtype, raws[11], 11),
    ]
    got = recording_from_raw(items, source="x", required=("pt_ct",)).streams["pt_ct"]
    want = recording_from_raw(((topic, msgtype, r) for r in raws), source="x", required=("pt_ct",)).streams["pt_ct"]
    assert np.array_equal(got.t_ns, want.t_ns) and got.t_ns.size == 12 * 7
    for c in want.channels:
        assert np.array_equal(got.channels[c], want.channels[c])
    assert got.msg_offsets.tolist() == list(range(0, 84, 7))
