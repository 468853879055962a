"""Single ``.mcap`` files (ROS 2 profile, cdr encoding, zstd chunks), through ``mcap``."""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from phid_ros.errors import BagError
from phid_ros.io.msg_schemas import typestore
from phid_ros.io.recording import (
    DEFAULT_BLOCK_SIZE,
    Recording,
    checked_payloads,
    describe_span,
    is_phid_topic,
    iter_recording_messages,
    recording_from_raw,
)
from phid_ros.io.topics import DEFAULT_NAMESPACE

METADATA_NAME = "phid"


def write_mcap(
    path: str | Path, rec: Recording, *, block_size: int = DEFAULT_BLOCK_SIZE, namespace: str = DEFAULT_NAMESPACE
) -> Path:
    return write_mcap_messages(
        path, iter_recording_messages(rec, block_size=block_size, namespace=namespace), metadata=rec.metadata
    )


class McapMessageWriter:
    """Messages into a new .mcap file as they come; chunks reach the disk as they fill, so a
    process killed mid-way leaves a file that reads up to its last whole chunk (with a warning)."""

    def __init__(self, path: str | Path, metadata: dict[str, str] | None = None) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f"{self.path}: already exists, not overwriting")
        self.store = typestore()
        self.metadata = metadata
        self._fh = self.path.open("wb")
        self._writer = Writer(self._fh, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="phid_ros")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}

    def write(self, log_ns: int, topic: str, msgtype: str, msg: object) -> None:
        if msgtype not in self._schemas:
            msgdef, _ = self.store.generate_msgdef(msgtype, ros_version=2)
            self._schemas[msgtype] = self._writer.register_schema(msgtype, "ros2msg", msgdef.encode())
        if topic not in self._channels:
            self._channels[topic] = self._writer.register_channel(topic, "cdr", self._schemas[msgtype])
        data = bytes(self.store.serialize_cdr(msg, msgtype))
        self._writer.add_message(self._channels[topic], log_time=log_ns, data=data, publish_time=log_ns)

    def close(self) -> Path:
        if self.metadata:
            self._writer.add_metadata(METADATA_NAME, {k: str(v) for k, v in self.metadata.items()})
        self._writer.finish()
        self._fh.close()
        return self.path

    def abort(self) -> None:
        self._fh.close()
        self.path.unlink(missing_ok=True)


def write_mcap_messages(
    path: str | Path, messages: Iterable[tuple[int, str, str, object]], metadata: dict[str, str] | None = None
) -> Path:
    """Any (log time ns, topic, msgtype, message) stream, in that order, into a new .mcap file."""
    writer = McapMessageWriter(path, metadata)
    try:
        for item in messages:
            writer.write(*item)
    except BaseException:
        writer.abort()  # never leave a truncated file that looks like a recording
        raise
    return writer.close()


def read_mcap(path: str | Path) -> Recording:
    """Fast record walker first; the ``mcap`` library reader where the walker does not apply."""
    from phid_ros.io.bags.mcap_raw import McapFormatError, WalkStatus, iter_message_runs

    path = Path(path)
    source = str(path)
    if not path.is_file():
        raise BagError(f"{source}: no such MCAP file")
    status = WalkStatus()
    try:
        rec = recording_from_raw(checked_payloads(iter_message_runs(path, status), source), source=source)
    except McapFormatError as exc:
        raise BagError(f"{source}: truncated or corrupt MCAP file: {exc}") from exc
    except BagError as exc:
        cut = status.truncation()
        if cut is None:
            raise
        raise BagError(f"{source}: {cut}, and what comes before the cut is not enough: {exc}") from exc
    cut = status.truncation()
    if cut is None:
        rec.metadata = file_metadata(path)
    else:  # the metadata index sits at the end that is missing: the recording is read without it
        rec.warnings.append(f"{source}: {cut}; {describe_span(rec)}")
    return rec


def file_metadata(path: Path) -> dict[str, str]:
    from mcap.reader import make_reader

    try:
        with path.open("rb") as fh:
            out: dict[str, str] = {}
            for record in make_reader(fh).iter_metadata():
                if record.name == METADATA_NAME:
                    out.update(record.metadata)
            return out
    except Exception as exc:  # the mcap reader raises assorted errors on damaged files
        raise BagError(f"{path}: truncated or corrupt MCAP file: {type(exc).__name__}: {exc}") from exc


def read_mcap_reference(path: str | Path) -> Recording:
    """Read through the ``mcap`` library reader: the reference path."""
    path = Path(path)
    source = str(path)
    if not path.is_file():
        raise BagError(f"{source}: no such MCAP file")
    store = typestore()
    metadata = file_metadata(path)
    try:
        with path.open("rb") as fh:
            reader = make_reader(fh)

            def items() -> Iterator[tuple[str, str, bytes]]:
                for schema, channel, message in reader.iter_messages(log_time_order=False):
                    if not is_phid_topic(channel.topic):
                        continue
                    if schema is None or channel.message_encoding != "cdr":
                        raise BagError(f"{source}: channel {channel.topic} is not cdr-encoded ROS 2 data")
                    if schema.name not in store.types:
                        raise BagError(f"{source}: topic {channel.topic} has unknown message type {schema.name}")
                    yield channel.topic, schema.name, message.data

            return recording_from_raw(items(), source=source, metadata=metadata)
    except BagError:
        raise
    except (McapError, EOFError, OSError, ValueError, json.JSONDecodeError) as exc:
        raise BagError(f"{source}: truncated or corrupt MCAP file: {exc}") from exc
    except Exception as exc:  # the mcap reader raises assorted errors on damaged records
        raise BagError(f"{source}: truncated or corrupt MCAP file: {type(exc).__name__}: {exc}") from exc
