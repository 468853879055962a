"""The fast MCAP walker against the ``mcap`` library's reader, and its order of errors."""

from __future__ import annotations

import itertools
import struct
from pathlib import Path

import pytest

from phid_ros.io.mcap_raw import LOOKAHEAD, MAGIC, McapFormatError, WalkStatus, iter_messages

CATALOGUE = Path(__file__).resolve().parents[2] / "bags" / "catalogue" / "catalogue.mcap"


def _chunks(data: bytes) -> list[tuple[int, int]]:
    """(start, end) of every top-level Chunk record."""
    pos, out = len(MAGIC), []
    while pos < len(data):
        op, length = struct.unpack_from("<BQ", data, pos)
        if op == 0x06:
            out.append((pos, pos + 9 + length))
        if op == 0x0F:
            break
        pos += 9 + length
    return out


def test_every_message_equals_the_mcap_readers_in_file_order():
    from mcap.reader import make_reader

    with CATALOGUE.open("rb") as f:
        want = [
            (channel.topic, schema.name, channel.message_encoding, message.data)
            for schema, channel, message in make_reader(f).iter_messages(log_time_order=False)
        ]
    st = WalkStatus()
    got = [(t, s, e, bytes(raw)) for t, s, e, raw in iter_messages(CATALOGUE, st)]
    assert len(got) == len(want) == 26_418
    assert got == want
    assert st.complete and st.truncation() is None


def test_a_damaged_chunk_beyond_the_lookahead_is_raised_after_every_message_before_it(tmp_path):
    """Chunks are decompressed ahead of the walk; an error met ahead waits its turn."""
    data = bytearray(CATALOGUE.read_bytes())
    chunks = _chunks(bytes(data))
    bad = 3 * LOOKAHEAD  # well past what is decompressed ahead when the walk starts
    before = sum(1 for _ in iter_messages(_write(tmp_path / "head.mcap", bytes(data[: chunks[bad][0]]))))
    start, end = chunks[bad]
    data[end - 200 : end - 100] = b"\x00" * 100  # inside the compressed bytes: zstd refuses the frame
    path = _write(tmp_path / "bad.mcap", bytes(data))
    seen = 0
    with pytest.raises(McapFormatError, match="damaged chunk"):
        for _ in iter_messages(path):
            seen += 1
    assert 0 < before == seen


def test_a_walk_abandoned_midway_leaves_no_thread_behind():
    import threading

    walk = iter_messages(CATALOGUE)
    assert len(list(itertools.islice(walk, 100))) == 100  # mid-walk: chunks are being decompressed ahead
    walk.close()
    assert not [t for t in threading.enumerate() if t.name.startswith("mcap-chunks")]


def _write(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path
