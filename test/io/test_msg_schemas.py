import re
from pathlib import Path

import numpy as np

from phid_ros.io.msg_schemas import INTERFACE_PACKAGE, msg_files, schema_dir, typestore
from phid_ros.io.topics import SCENARIO_MSGTYPE, STREAMS

ROOT = Path(__file__).resolve().parents[2]


def test_cmakelists_generates_every_msg_file():
    cmake = (ROOT / "msg_schemas" / "CMakeLists.txt").read_text()
    listed = set(re.findall(r'"msg/(\w+)\.msg"', cmake))
    on_disk = {p.stem for p in (ROOT / "msg_schemas" / "msg").glob("*.msg")}
    assert listed == on_disk and len(on_disk) >= 9
    assert f"<name>{INTERFACE_PACKAGE}</name>" in (ROOT / "msg_schemas" / "package.xml").read_text()
    assert f"<depend>{INTERFACE_PACKAGE}</depend>" in (ROOT / "package.xml").read_text()


def test_typestore_knows_every_message_and_the_stream_fields():
    store = typestore()
    for name in msg_files():
        assert name in store.types
    for spec in STREAMS:
        fields = [f[0] for f in store.fielddefs[spec.msgtype][1]]
        assert fields == ["header", "sample_period", *spec.channels]
    assert SCENARIO_MSGTYPE in store.types
    assert schema_dir().name in ("msg_schemas", "msg_schemas_data")


def test_block_message_serialises_and_round_trips_arrays():
    store = typestore()
    cls = store.types["phid_msgs/msg/PtCtBlock"]
    hdr = store.types["std_msgs/msg/Header"](
        stamp=store.types["builtin_interfaces/msg/Time"](sec=5, nanosec=7), frame_id="g"
    )
    data = {c: np.arange(4, dtype=float) + i for i, c in enumerate(("v_t", "i_d", "i_q", "p_e", "q_e"))}
    msg = cls(header=hdr, sample_period=1e-3, **data)
    raw = store.serialize_cdr(msg, "phid_msgs/msg/PtCtBlock")
    back = store.deserialize_cdr(raw, "phid_msgs/msg/PtCtBlock")
    assert back.header.stamp.nanosec == 7
    for c, v in data.items():
        assert np.array_equal(getattr(back, c), v)


def test_base_types_equal_the_full_jazzy_store():
    from rosbags.typesys import Stores, get_typestore

    full = get_typestore(Stores.ROS2_JAZZY)
    ours = typestore()
    from phid_ros.io.msg_schemas import BASE_TYPES

    for name in BASE_TYPES:
        assert ours.hash_rihs01(name) == full.hash_rihs01(name)
        assert ours.generate_msgdef(name, ros_version=2) == full.generate_msgdef(name, ros_version=2)
