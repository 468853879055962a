"""rosbag2 folders with MCAP storage (zstd chunk compression), through ``rosbags``."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2.errors import ReaderError, WriterError

from phid_ros.errors import BagError
from phid_ros.io.msg_schemas import typestore
from phid_ros.io.recording import (
    DEFAULT_BLOCK_SIZE,
    Recording,
    is_phid_topic,
    recording_from_raw,
    recording_messages,
)
from phid_ros.io.topics import DEFAULT_NAMESPACE

ROSBAG2_VERSION = 9  # what ROS 2 Jazzy writes


def write_rosbag2(path: str | Path, rec: Recording, *, block_size: int = DEFAULT_BLOCK_SIZE,
                  namespace: str = DEFAULT_NAMESPACE) -> Path:
    path = Path(path)
    if path.exists():
        raise BagError(f"{path}: already exists, not overwriting")
    store = typestore()
    writer = Writer(path, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin.MCAP)
    writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    for key, value in rec.metadata.items():
        writer.set_custom_data(f"phid.{key}", str(value))
    try:
        writer.open()
        connections: dict[str, object] = {}
        for log_ns, topic, msgtype, msg in recording_messages(rec, block_size=block_size, namespace=namespace):
            conn = connections.get(topic)
            if conn is None:
                conn = connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(conn, log_ns, store.serialize_cdr(msg, msgtype))  # type: ignore[arg-type]
    except WriterError as exc:
        raise BagError(f"{path}: cannot write bag: {exc}") from exc
    finally:
        if writer.storage is not None:
            writer.close()
    return path


def _iter_raw(reader: Reader, source: str) -> Iterator[tuple[str, str, bytes]]:
    store = typestore()
    ours = [c for c in reader.connections if is_phid_topic(c.topic)]
    if not ours:
        present = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
        raise BagError(f"{source}: none of the phid sensor topics found (topics present: {present})")
    for conn, _, raw in reader.messages(connections=ours):
        if conn.msgtype not in store.types:
            raise BagError(f"{source}: topic {conn.topic} has unknown message type {conn.msgtype}")
        yield conn.topic, conn.msgtype, raw


def read_rosbag2(path: str | Path) -> Recording:
    path = Path(path)
    source = str(path)
    if not path.exists():
        raise BagError(f"{source}: no such bag")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise BagError(f"{source}: not a rosbag2 folder (metadata.yaml missing)")
    try:
        with Reader(path) as reader:
            custom = getattr(reader.storage, "metadata", None)
            custom_data = dict(getattr(custom, "custom", None) or {})
            metadata = {k[len("phid."):]: v for k, v in custom_data.items() if k.startswith("phid.")}
            return recording_from_raw(_iter_raw(reader, source), source=source, metadata=metadata)
    except ReaderError as exc:
        raise BagError(f"{source}: cannot read bag: {exc}") from exc
    except (EOFError, OSError, KeyError) as exc:
        raise BagError(f"{source}: truncated or corrupt bag: {exc}") from exc
