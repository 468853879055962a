"""The bag writer in a thread of its own: the same bytes as a direct write, and a writer's error
(a full disk) raised in the producer's thread, the producer never left blocked."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest

from phid_ros.io.bags.recordings import BackgroundWriter, open_message_writer
from phid_ros.io.recording import recording_messages


@pytest.mark.parametrize("suffix", [".mcap", ""])
def test_a_background_write_is_byte_identical_to_a_direct_one(tmp_path, short_recording, suffix):
    messages = list(recording_messages(short_recording, block_size=7))  # many batches of 256
    assert len(messages) > 5 * BackgroundWriter.BATCH
    paths = []
    for background in (False, True):
        path = tmp_path / str(background) / f"out{suffix}"  # one name: a rosbag2 folder names its files after it
        path.parent.mkdir()
        w = open_message_writer(path, {"source": "test"}, background=background)
        assert isinstance(w, BackgroundWriter) == background
        for item in messages:
            w.write(*item)
        paths.append(w.close())
    files = [sorted(p.rglob("*")) if p.is_dir() else [p] for p in paths]
    assert [f.name for f in files[0]] != [] and len(files[0]) == len(files[1])
    for a, b in zip(*files, strict=True):
        assert a.is_dir() or a.read_bytes() == b.read_bytes(), a.name


class _FullDisk:
    """A writer that fails at its 300th message, as a full disk does."""

    def __init__(self) -> None:
        self.written = 0
        self.aborted = False

    def write(self, log_ns: int, topic: str, msgtype: str, msg: object) -> None:
        if self.written == 300:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.written += 1

    def close(self) -> Path:
        return Path("never")

    def abort(self) -> None:
        self.aborted = True


def test_a_writer_s_error_reaches_the_producer_and_nothing_blocks():
    inner = _FullDisk()
    w = BackgroundWriter(inner)
    with pytest.raises(OSError, match="No space left on device"):
        # far more batches than the queue holds: the producer is never left waiting on a dead writer
        for k in range(BackgroundWriter.BATCH * (BackgroundWriter.DEPTH + 8)):
            w.write(k, "/t", "std_msgs/msg/String", None)
    assert inner.written == 300
    w.abort()
    assert inner.aborted


def test_an_error_in_the_last_batch_is_raised_by_close():
    inner = _FullDisk()
    w = BackgroundWriter(inner)
    for k in range(301):  # fewer than a batch: written only when closing
        w.write(k, "/t", "std_msgs/msg/String", None)
    with pytest.raises(OSError, match="No space left on device"):
        w.close()
