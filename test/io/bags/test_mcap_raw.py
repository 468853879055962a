"""The fast MCAP walker against the ``mcap`` library's reader, and its order of errors."""

from __future__ import annotations

import itertools
import struct
from pathlib import Path

import pytest

from phid_ros.io.bags.mcap_raw import LOOKAHEAD, MAGIC, McapFormatError, WalkStatus, iter_messages

CATALOGUE = Path(__file__).resolve().parents[3] / "bags" / "catalogue" / "catalogue.mcap"


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


# -- runs: the messages of a repeating cycle of records as strided views --------------------------


def _expanded(path: Path, status: WalkStatus | None = None) -> tuple[list[tuple[int, str, str, str, bytes]], int]:
    """Every message of a walk with positions, runs expanded, in position order; and the runs seen."""
    import numpy as np

    from phid_ros.io.bags.mcap_raw import iter_message_runs

    out, runs = [], 0
    for t, s, e, payload, pos in iter_message_runs(path, status):
        if isinstance(payload, np.ndarray):
            runs += 1
            assert payload.ndim == 2 and len(payload) == len(pos) and not payload.flags.writeable
            out += [(int(p), t, s, e, bytes(row)) for p, row in zip(pos, payload)]
        else:
            out.append((pos, t, s, e, bytes(payload)))
    return sorted(out), runs


def test_runs_are_the_messages_in_file_order_position_for_position():
    st = WalkStatus()
    got, runs = _expanded(CATALOGUE, st)
    want = [(i, t, s, e, bytes(raw)) for i, (t, s, e, raw) in enumerate(iter_messages(CATALOGUE))]
    assert got == want
    assert runs > 100 and st.messages == 26_418  # the catalogue's chunks are cycles of four channels


def _irregular(path: Path, damage: bool = False) -> Path:
    """An uncompressed MCAP whose chunks repeat a cycle of three channels, broken by: a longer
    message, a channel registered mid-chunk, a lone message of another channel; and, with
    ``damage``, a record whose length runs past its chunk, deep inside a cycle."""
    from mcap.writer import CompressionType, Writer

    with path.open("wb") as f:
        w = Writer(f, compression=CompressionType.NONE, chunk_size=40_000)
        w.start(profile="ros2", library="test")
        sid = w.register_schema("pkg/msg/X", "ros2msg", b"float64 x")
        ch = [w.register_channel(f"/t{i}", "cdr", sid) for i in range(3)]
        late = None
        t = 0
        for k in range(400):
            for i, c in enumerate(ch):
                size = 40 + 8 * i + (16 if (k, i) == (150, 1) else 0)
                w.add_message(c, log_time=t, data=bytes([k % 251, i]) * (size // 2), publish_time=t)
                t += 1
            if k == 220:
                late = w.register_channel("/late", "cdr", sid)
            if late is not None and k % 97 == 0:
                w.add_message(late, log_time=t, data=b"late", publish_time=t)
                t += 1
        w.finish()
    if damage:
        data = bytearray(path.read_bytes())
        start, _ = _chunks(bytes(data))[1]
        # the chunk's records begin after its header (4 u64/u32 fields, a compression string, a length)
        body = start + 9 + 8 + 8 + 8 + 4 + 4 + 8
        pos = body
        for _ in range(60):  # deep into the chunk's cycles
            pos += 9 + struct.unpack_from("<Q", data, pos + 1)[0]
        struct.pack_into("<Q", data, pos + 1, 10**9)
        path.write_bytes(bytes(data))
    return path


def test_a_cycle_broken_by_a_longer_message_a_new_channel_or_a_lone_one_walks_as_the_plain_walk(tmp_path):
    path = _irregular(tmp_path / "irregular.mcap")
    got, runs = _expanded(path)
    want = [(i, t, s, e, bytes(raw)) for i, (t, s, e, raw) in enumerate(iter_messages(path))]
    assert len(want) == 400 * 3 + 2 and got == want  # /late at k = 291 and 388
    assert runs >= 3 * len(_chunks(path.read_bytes())) // 2  # most chunks walked as runs


def test_a_damaged_record_inside_a_cycle_raises_the_plain_walks_error_after_the_same_messages(tmp_path):
    path = _irregular(tmp_path / "damaged.mcap", damage=True)
    from phid_ros.io.bags.mcap_raw import iter_message_runs

    def walk(it: object) -> tuple[int, str]:
        seen = 0
        with pytest.raises(McapFormatError) as err:
            for item in it:  # type: ignore[attr-defined]
                seen += len(item[4]) if len(item) > 4 and not isinstance(item[4], int) else 1
        return seen, str(err.value)

    plain, runs = walk(iter_messages(path)), walk(iter_message_runs(path))
    assert plain == runs and plain[0] > 0 and "past the end" in plain[1]


@pytest.mark.parametrize("seed", range(6))
def test_runs_agree_with_the_plain_walk_on_random_record_patterns(tmp_path, seed):
    """Cycles of 1 to 6 channels, channels sharing one length, a cycle changing its order or a
    message its length now and then, lone messages, chunks of many sizes: the walk with runs
    gives every message, byte for byte, at the plain walk's position."""
    import numpy as np
    from mcap.writer import CompressionType, Writer

    rng = np.random.default_rng(seed)
    path = tmp_path / f"random{seed}.mcap"
    with path.open("wb") as f:
        w = Writer(f, compression=CompressionType.NONE, chunk_size=int(rng.integers(4_000, 30_000)))
        w.start(profile="ros2", library="test")
        sid = w.register_schema("pkg/msg/X", "ros2msg", b"float64 x")
        chans = [w.register_channel(f"/c{i}", "cdr", sid) for i in range(8)]
        t = 0
        for _ in range(int(rng.integers(5, 12))):  # stretches, each its own cycle
            cycle = [int(c) for c in rng.choice(8, size=int(rng.integers(1, 7)), replace=False)]
            sizes = {c: int(rng.choice([24, 24, 40, 64])) for c in cycle}  # lengths shared by channels
            for _ in range(int(rng.integers(20, 60))):
                for c in cycle:
                    size = sizes[c] + (8 if rng.random() < 0.02 else 0)  # now and then a longer one
                    w.add_message(chans[c], log_time=t, data=rng.bytes(size), publish_time=t)
                    t += 1
                if rng.random() < 0.03:
                    w.add_message(chans[int(rng.integers(8))], log_time=t, data=rng.bytes(5), publish_time=t)
                    t += 1
        w.finish()
    got, runs = _expanded(path)
    want = [(i, tp, s, e, bytes(raw)) for i, (tp, s, e, raw) in enumerate(iter_messages(path))]
    assert got == want and len(want) == t
    assert runs > 0  # the runs were exercised, not only the plain loop
