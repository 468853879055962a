"""rosbag2 folders with MCAP storage (zstd chunk compression), through ``rosbags``."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Literal

from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2.errors import ReaderError, WriterError

from phid_ros.errors import BagError
from phid_ros.io.files.outputs import final_name
from phid_ros.io.msg_schemas import typestore
from phid_ros.io.recording import (
    DEFAULT_BLOCK_SIZE,
    Recording,
    checked_payloads,
    describe_span,
    expected_type,
    is_phid_topic,
    iter_recording_messages,
    recording_from_raw,
)
from phid_ros.io.topics import DEFAULT_NAMESPACE

ROSBAG2_VERSION: Literal[8, 9] = 9  # what ROS 2 Jazzy writes


def write_rosbag2(
    path: str | Path, rec: Recording, *, block_size: int = DEFAULT_BLOCK_SIZE, namespace: str = DEFAULT_NAMESPACE
) -> Path:
    return write_rosbag2_messages(
        path, iter_recording_messages(rec, block_size=block_size, namespace=namespace), metadata=rec.metadata
    )


class Rosbag2MessageWriter:
    """Messages into a new rosbag2 folder (MCAP storage, zstd) as they come."""

    def __init__(self, path: str | Path, metadata: dict[str, str] | None = None) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f"{self.path}: already exists, not overwriting")
        self.store = typestore()
        self._writer = Writer(self.path, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin.MCAP)
        self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        for key, value in (metadata or {}).items():
            self._writer.set_custom_data(f"phid.{key}", str(value))
        try:
            self._writer.open()
        except WriterError as exc:
            raise BagError(f"{self.path}: cannot write bag: {exc}") from exc
        self._connections: dict[str, object] = {}

    def write(self, log_ns: int, topic: str, msgtype: str, msg: object) -> None:
        conn = self._connections.get(topic)
        if conn is None:
            conn = self._connections[topic] = self._writer.add_connection(topic, msgtype, typestore=self.store)
        self._writer.write(conn, log_ns, self.store.serialize_cdr(msg, msgtype))  # type: ignore[arg-type]

    def close(self) -> Path:
        self._writer.close()
        self._name_storage(final_name(self.path.name))
        return self.path

    def _name_storage(self, name: str) -> None:
        """The storage file named after the bag's final folder name.

        rosbags names it after the folder, which is still the ``.partial`` staging folder while
        an output is written (phid_ros.io.files.outputs): shipped bags said ``x.partial.mcap``, which
        reads as an interrupted recording.
        """
        built = f"{self.path.name}.mcap"
        if name == self.path.name or not (self.path / built).exists():
            return
        meta = self.path / "metadata.yaml"
        os.replace(self.path / built, self.path / f"{name}.mcap")
        meta.write_text(meta.read_text(encoding="utf-8").replace(built, f"{name}.mcap"), encoding="utf-8")

    def abort(self) -> None:
        if self._writer.storage is not None:
            self._writer.storage.abort()  # close the file without index and footer
        shutil.rmtree(self.path, ignore_errors=True)  # never leave a half-written bag behind


def write_rosbag2_messages(
    path: str | Path, messages: Iterable[tuple[int, str, str, object]], metadata: dict[str, str] | None = None
) -> Path:
    """Any (log time ns, topic, msgtype, message) stream, in that order, into a new rosbag2 folder."""
    writer = Rosbag2MessageWriter(path, metadata)
    try:
        for item in messages:
            writer.write(*item)
    except BaseException as exc:
        writer.abort()
        if isinstance(exc, WriterError):
            raise BagError(f"{path}: cannot write bag: {exc}") from exc
        raise
    return writer.close()


def _iter_raw(reader: Reader, source: str) -> Iterator[tuple[str, str, bytes]]:
    store = typestore()
    ours = [c for c in reader.connections if is_phid_topic(c.topic)]
    if not ours:
        present = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
        raise BagError(f"{source}: none of the phid sensor topics found (topics present: {present})")
    for conn, _, raw in reader.messages(connections=ours):
        expected = expected_type(conn.topic)
        if expected is not None and conn.msgtype != expected:
            raise BagError(f"{source}: topic {conn.topic} has type {conn.msgtype}, expected {expected}")
        if conn.msgtype not in store.types:
            raise BagError(f"{source}: topic {conn.topic} has unknown message type {conn.msgtype}")
        yield conn.topic, conn.msgtype, raw


MAX_METADATA_BYTES = 1 << 20  # a bag's metadata.yaml: a few KB


def bag_metadata(path: Path) -> dict:
    """``rosbag2_bagfile_information`` of a bag folder's metadata.yaml, every scalar as its text.

    Read by libyaml (PyYAML's C loader; 1 ms, where ruamel's pure-Python loader took 20 ms and
    15 ms more to import) and without YAML 1.1's type guessing, which would turn a custom_data
    value such as ``yes`` or ``1:30`` into another string than the one written. An empty
    field reads as its text too (``null``, ``~``), not as None.
    """
    import yaml

    loader = getattr(yaml, "CBaseLoader", yaml.BaseLoader)
    with open(path / "metadata.yaml", "rb") as f:
        text = f.read(MAX_METADATA_BYTES + 1)
    if len(text) > MAX_METADATA_BYTES:
        raise BagError(f"{path / 'metadata.yaml'}: more than {MAX_METADATA_BYTES >> 20} MB: not a bag's metadata")
    # rosbag2 writes no aliases; a few hundred bytes of nested ones expand to gigabytes when walked
    if any(isinstance(e, yaml.AliasEvent) for e in yaml.parse(text, Loader=loader)):
        raise BagError(f"{path / 'metadata.yaml'}: holds YAML aliases, which rosbag2 never writes")
    return yaml.load(text, Loader=loader)["rosbag2_bagfile_information"]


def mcap_storage(path: Path) -> tuple[list[Path], dict[str, str]] | None:
    """A bag folder's storage files, when our MCAP walker reads them (uncompressed MCAP), and
    its phid metadata; None for other storage (the rosbags reader's)."""
    try:
        meta = bag_metadata(path)
    except Exception:
        return None
    if meta.get("storage_identifier") != "mcap" or meta.get("compression_mode"):
        return None
    files = [path / Path(f).name for f in meta.get("relative_file_paths", [])]
    if not files or not all(f.is_file() for f in files):
        return None
    custom = meta.get("custom_data")
    custom = custom if isinstance(custom, dict) else {}  # "null" (no custom data), as its text
    return files, {k[len("phid.") :]: str(v) for k, v in custom.items() if k.startswith("phid.")}


def _fast_read(path: Path, source: str) -> Recording | None:
    """Our own MCAP walker over the bag's storage files; None when it cannot apply."""
    from phid_ros.io.bags.mcap_raw import McapFormatError, WalkStatus, iter_message_runs

    storage = mcap_storage(path)
    if storage is None:
        return None
    files, metadata = storage
    statuses = {f: WalkStatus() for f in files}

    def items() -> Iterator[tuple]:
        first = 0  # positions count on across a split bag's files
        for f in files:
            yield from checked_payloads(iter_message_runs(f, statuses[f], first), source)
            first += statuses[f].messages

    try:
        rec = recording_from_raw(items(), source=source, metadata=metadata)
    except McapFormatError as exc:
        raise BagError(f"{source}: truncated or corrupt bag: {exc}") from exc
    except BagError as exc:
        cuts = [f"{f}: {st.truncation()}" for f, st in statuses.items() if st.truncation()]
        if not cuts:
            raise
        raise BagError(f"{'; '.join(cuts)}, and what comes before the cut is not enough: {exc}") from exc
    for f, st in statuses.items():
        cut = st.truncation()
        if cut:
            rec.warnings.append(f"{f}: {cut}; {describe_span(rec)}")
    return rec


def read_rosbag2(path: str | Path) -> Recording:
    path = Path(path)
    source = str(path)
    if not path.exists():
        raise BagError(f"{source}: no such bag")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise BagError(f"{source}: not a rosbag2 folder (metadata.yaml missing)")
    if path.is_dir():
        fast = _fast_read(path, source)
        if fast is not None:
            return fast
    return read_rosbag2_reference(path)


def read_rosbag2_reference(path: str | Path) -> Recording:
    """Read through the rosbags reader (any storage, any compression): the reference path."""
    path = Path(path)
    source = str(path)
    try:
        with Reader(path) as reader:
            custom = getattr(reader.storage, "metadata", None)
            custom_data = dict(getattr(custom, "custom", None) or {})
            metadata = {k[len("phid.") :]: v for k, v in custom_data.items() if k.startswith("phid.")}
            return recording_from_raw(_iter_raw(reader, source), source=source, metadata=metadata)
    except ReaderError as exc:
        raise BagError(f"{source}: cannot read bag: {exc}") from exc
    except (EOFError, OSError, KeyError) as exc:
        raise BagError(f"{source}: truncated or corrupt bag: {exc}") from exc
