"""The vectorised block decoder agrees with the rosbags deserialiser, and falls back when it must."""

from __future__ import annotations

import numpy as np

from phid_ros.io.cdr_blocks import block_layout, decode_group, group_by_layout
from phid_ros.io.msg_schemas import typestore
from phid_ros.io.recording import recording_from_messages, recording_from_raw, recording_messages


def _pt_ct(n: int, frame_id: str = "generator", sec: int = 5):
    store = typestore()
    hdr = store.types["std_msgs/msg/Header"](
        stamp=store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=9), frame_id=frame_id
    )
    rng = np.random.default_rng(n)
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
    groups, rest = group_by_layout(list(raws), 5)
    assert rest == [] and len(groups) == 1
    layout, idx = next(iter(groups.items()))
    dec = decode_group([raws[i] for i in idx], idx, layout, 5)
    assert dec is not None
    assert list(dec.t0_ns) == [s * 1_000_000_000 + 9 for s in range(4)]
    for j, c in enumerate(("v_t", "i_d", "i_q", "p_e", "q_e")):
        assert np.array_equal(dec.values[j], np.stack([a[c] for a in arrays]))


def test_unequal_arrays_fall_back_to_the_reference_and_are_refused():
    store = typestore()
    raw, _ = _pt_ct(4)
    msg = store.deserialize_cdr(raw, "phid_msgs/msg/PtCtBlock")
    msg.q_e = np.zeros(3)
    bad = bytes(store.serialize_cdr(msg, "phid_msgs/msg/PtCtBlock"))
    groups, rest = group_by_layout([bad], 5)
    assert rest == [0]
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
