"""Vectorised decoding of the sensor block messages (``*Block.msg``) from raw CDR.

All block messages of one type with the same frame_id and block length have the
same byte layout, so a group of them decodes as one numpy view at fixed offsets
instead of one Python deserialisation per message (about 25x faster on the
catalogue bag). Layout (CDR, little endian, offsets from the body start):

    int32 sec, uint32 nanosec, uint32 len + frame_id + NUL, pad to 8,
    float64 sample_period, then per channel: pad to 4, uint32 count, pad to 8,
    count x float64.

Anything that does not match that layout exactly (big endian, unequal array
lengths, a count that disagrees) goes through the rosbags deserialiser, which
is the reference; tests check that both paths agree.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from phid_ros.model.conventions import NS

CDR_LE_HEADER = b"\x00\x01\x00\x00"
ENCAPSULATION = 4


def _align(pos: int, n: int) -> int:
    return (pos + n - 1) // n * n


@dataclass(frozen=True)
class BlockLayout:
    """Byte offsets (from the start of the raw message) of one block shape."""

    total: int
    sec: int
    nanosec: int
    period: int
    counts: tuple[int, ...]
    data: tuple[int, ...]
    n: int


def block_layout(frame_id_len: int, n_channels: int, n: int) -> BlockLayout:
    pos = 12 + frame_id_len + 1  # sec, nanosec, string length, chars, NUL
    pos = _align(pos, 8)
    period = pos
    pos += 8
    counts, data = [], []
    for _ in range(n_channels):
        pos = _align(pos, 4)
        counts.append(pos)
        pos += 4
        if n:
            pos = _align(pos, 8)
        data.append(pos)
        pos += 8 * n
    e = ENCAPSULATION
    return BlockLayout(
        total=pos + e,
        sec=e,
        nanosec=e + 4,
        period=period + e,
        counts=tuple(c + e for c in counts),
        data=tuple(d + e for d in data),
        n=n,
    )


def _guess_layout(raw: bytes, n_channels: int) -> BlockLayout | None:
    if len(raw) < 16 or raw[:4] != CDR_LE_HEADER:
        return None
    flen = int.from_bytes(raw[12:16], "little") - 1
    if flen < 0 or 16 + flen >= len(raw):
        return None
    # the element count of the first array fixes n; the whole size must then agree
    probe = block_layout(flen, n_channels, 0)
    if probe.counts[0] + 4 > len(raw):
        return None
    n = int.from_bytes(raw[probe.counts[0] : probe.counts[0] + 4], "little")
    layout = block_layout(flen, n_channels, n)
    return layout if layout.total == len(raw) else None


@dataclass
class DecodedGroup:
    order: NDArray[np.int64]  # index of each message in the stream's message order
    t0_ns: NDArray[np.int64]
    period_s: NDArray[np.float64]
    values: list[NDArray[np.float64]]  # per channel, shape (messages, n)


def decode_group(
    raws: Sequence[bytes], order: Sequence[int], layout: BlockLayout, n_channels: int
) -> DecodedGroup | None:
    """Decode equally shaped messages at once; None if any message breaks the layout."""
    buf = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(len(raws), layout.total)

    joined = buf.base if buf.base is not None else buf
    total = layout.total

    def field(offset: int, dtype: str, count: int = 1) -> NDArray:
        # a strided view into the joined bytes, no copy (the assembly copies once, into the
        # stream); CDR aligns from the body, so float64 fields sit 4 bytes off: numpy allows it
        return np.ndarray(
            (len(raws), count), dtype=dtype, buffer=joined, offset=offset, strides=(total, np.dtype(dtype).itemsize)
        )

    if not np.all(buf[:, :4] == np.frombuffer(CDR_LE_HEADER, dtype=np.uint8)):
        return None
    if not np.all(buf[:, 12:16] == buf[0, 12:16]):  # every frame_id of the same length
        return None
    for c in layout.counts:
        if not np.all(field(c, "<u4")[:, 0] == layout.n):
            return None
    sec = field(layout.sec, "<i4")[:, 0].astype(np.int64)
    nsec = field(layout.nanosec, "<u4")[:, 0].astype(np.int64)
    return DecodedGroup(
        order=np.asarray(order, dtype=np.int64),
        t0_ns=sec * NS + nsec,
        period_s=field(layout.period, "<f8")[:, 0],
        values=[field(d, "<f8", layout.n) for d in layout.data],
    )


def group_by_layout(raws: Sequence[bytes], n_channels: int) -> tuple[dict[BlockLayout, list[int]], list[int]]:
    """Message indices per layout, and the indices that need the generic deserialiser.

    Grouping is by message length (numpy); :func:`decode_group` then checks that
    every message of a group really has the layout of its first one.
    """
    lengths = np.fromiter((len(r) for r in raws), dtype=np.int64, count=len(raws))
    groups: dict[BlockLayout, list[int]] = {}
    rest: list[int] = []
    for length in np.unique(lengths):
        idx = np.flatnonzero(lengths == length)
        layout = _guess_layout(bytes(raws[int(idx[0])]), n_channels)
        if layout is None:
            rest.extend(idx.tolist())
        else:
            groups.setdefault(layout, []).extend(idx.tolist())
    return groups, rest
