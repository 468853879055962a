"""One entry point for recordings on disk: a rosbag2 folder or a single .mcap file."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Protocol

from phid_ros.errors import BagError
from phid_ros.io.bags.mcap_file import read_mcap, write_mcap
from phid_ros.io.bags.rosbag2 import read_rosbag2, write_rosbag2
from phid_ros.io.recording import Recording


def is_mcap_file(path: Path) -> bool:
    return path.suffix == ".mcap" and not path.is_dir()


def read_recording(path: str | Path) -> Recording:
    p = Path(path)
    if not p.exists():
        raise BagError(f"{p}: no such bag or MCAP file")
    if p.is_dir():
        return read_rosbag2(p)
    if is_mcap_file(p):
        return read_mcap(p)
    raise BagError(f"{p}: not a rosbag2 folder or .mcap file")


def write_messages(
    path: str | Path, messages: Iterable[tuple[int, str, str, object]], metadata: dict[str, str] | None = None
) -> Path:
    """(log time, topic, msgtype, message) in log-time order -> ``*.mcap`` file or rosbag2 folder."""
    from phid_ros.io.bags.mcap_file import write_mcap_messages
    from phid_ros.io.bags.rosbag2 import write_rosbag2_messages

    p = Path(path)
    if p.suffix == ".mcap":
        return write_mcap_messages(p, messages, metadata)
    return write_rosbag2_messages(p, messages, metadata)


class MessageWriter(Protocol):
    """Messages into a new recording as they come (:class:`McapMessageWriter`, :class:`Rosbag2MessageWriter`)."""

    def write(self, log_ns: int, topic: str, msgtype: str, msg: object) -> None: ...

    def close(self) -> Path: ...

    def abort(self) -> None: ...


def open_message_writer(
    path: str | Path, metadata: dict[str, str] | None = None, *, background: bool = False
) -> MessageWriter:
    """``*.mcap`` -> a single MCAP file, anything else -> a rosbag2 folder; ``background``: written
    by a thread of its own (:class:`BackgroundWriter`)."""
    from phid_ros.io.bags.mcap_file import McapMessageWriter
    from phid_ros.io.bags.rosbag2 import Rosbag2MessageWriter

    p = Path(path)
    writer = McapMessageWriter(p, metadata) if p.suffix == ".mcap" else Rosbag2MessageWriter(p, metadata)
    return BackgroundWriter(writer) if background else writer


class BackgroundWriter:
    """A writer's work (serialising, compressing, writing) in a thread of its own, fed in batches.

    Why: a replay's producer waits for each recalibration run (its outcome is taken at a fixed
    stream time, so that the outputs do not depend on the machine's speed); the messages made
    before the wait are written meanwhile, and zstd compresses without the GIL. The messages
    reach the file in the order they were given: the file is byte-identical to a direct write.
    The queue is bounded, so a slow disk holds the producer back instead of filling memory; an
    error of the writer (a full disk) is raised by the next ``write`` or by ``close``.
    """

    BATCH = 256  # messages handed over at a time: one queue operation per batch, not per message
    DEPTH = 16  # batches in flight at most (a few MB of messages)

    def __init__(self, writer: MessageWriter) -> None:
        import queue
        import threading

        self.writer = writer
        self._batch: list[tuple[int, str, str, object]] = []
        self._queue: queue.Queue[list[tuple[int, str, str, object]] | None] = queue.Queue(self.DEPTH)
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._drain, name="phid-bag-writer", daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        while (batch := self._queue.get()) is not None:
            if self._error is not None:
                continue  # after an error the rest is dropped, so the producer is never blocked
            try:
                for item in batch:
                    self.writer.write(*item)
            except BaseException as exc:  # handed to the producer's thread, raised there
                self._error = exc

    def _raise(self) -> None:
        if self._error is not None:
            raise self._error

    def write(self, log_ns: int, topic: str, msgtype: str, msg: object) -> None:
        self._batch.append((log_ns, topic, msgtype, msg))
        if len(self._batch) >= self.BATCH:
            self._raise()
            self._queue.put(self._batch)
            self._batch = []

    def _stop(self) -> None:
        if self._thread.is_alive():
            self._queue.put(self._batch)
            self._batch = []
            self._queue.put(None)
            self._thread.join()

    def close(self) -> Path:
        self._stop()
        self._raise()
        return self.writer.close()

    def abort(self) -> None:
        self._stop()
        self.writer.abort()


def recording_source(path: str | Path) -> str | None:
    """The ``source`` a phid tool wrote into a bag's metadata (who made it), or None."""
    p = Path(path)
    try:
        if p.is_dir():
            from phid_ros.io.bags.rosbag2 import bag_metadata

            custom = bag_metadata(p).get("custom_data")
            return custom.get("phid.source") if isinstance(custom, dict) else None
        from phid_ros.io.bags.mcap_file import file_metadata

        return file_metadata(p).get("source")
    except Exception:  # not a bag, damaged, foreign: then it is not ours
        return None


def write_recording(path: str | Path, rec: Recording, **kwargs: object) -> Path:
    """``*.mcap`` -> single MCAP file; anything else -> rosbag2 folder (MCAP storage)."""
    p = Path(path)
    if p.suffix == ".mcap":
        return write_mcap(p, rec, **kwargs)  # type: ignore[arg-type]
    return write_rosbag2(p, rec, **kwargs)  # type: ignore[arg-type]


def walked_topic_table(path: str | Path) -> tuple[list[tuple[str, str, int]], list[str]]:
    """(topic, type, count) by walking every record, for a file whose index is missing (cut short),
    with a warning per file that was truncated; raises BagError when not even that works."""
    from phid_ros.io.bags.mcap_raw import McapFormatError, WalkStatus, iter_messages

    p = Path(path)
    files = sorted(p.glob("*.mcap")) if p.is_dir() else [p]
    counts: dict[tuple[str, str], int] = {}
    warnings = []
    for f in files:
        st = WalkStatus()
        try:
            for topic, schema, _, _ in iter_messages(f, st):
                counts[(topic, schema)] = counts.get((topic, schema), 0) + 1
        except McapFormatError as exc:
            raise BagError(f"{f}: truncated or corrupt MCAP file: {exc}") from exc
        cut = st.truncation()
        if cut:
            total = sum(counts.values())
            warnings.append(f"{f}: {cut}; read {total} whole messages before the cut")
    return sorted((t, s or "?", n) for (t, s), n in counts.items()), warnings


def topic_table(path: str | Path) -> list[tuple[str, str, int]]:
    """(topic, message type, message count) from the file's index, without decoding messages."""
    p = Path(path)
    if not p.exists():
        raise BagError(f"{p}: no such bag or MCAP file")
    try:
        if p.is_dir():
            from rosbags.rosbag2 import Reader

            with Reader(p) as reader:
                return sorted((t, info.msgtype or "?", info.msgcount) for t, info in reader.topics.items())
        from mcap.reader import make_reader

        with p.open("rb") as fh:
            summary = make_reader(fh).get_summary()
            if summary is None:
                raise BagError(f"{p}: MCAP file has no summary section (truncated?)")
            counts = summary.statistics.channel_message_counts if summary.statistics else {}
            return sorted(
                (
                    ch.topic,
                    summary.schemas[ch.schema_id].name if ch.schema_id in summary.schemas else "?",
                    counts.get(cid, 0),
                )
                for cid, ch in summary.channels.items()
            )
    except BagError:
        raise
    except Exception as exc:  # both readers raise assorted errors on damaged files
        raise BagError(f"{p}: cannot read index: {type(exc).__name__}: {exc}") from exc
