"""A COMTRADE recording's samples read in chunks: only the channels asked for, kept in the
recorder's own number type until they are used.

The ``comtrade`` package parses the configuration (.cfg, or the CFG section of a .cff); its
data reader holds every value of every channel as a Python float (a 2 h, 1 kHz recording of
ten channels: 72 million objects, over 2 GB), so the data (.dat, or the DAT section of a
.cff) are read here, ``CHUNK_ROWS`` rows at a time, with the same meaning the package gives
them (value = a * stored + b, in float64 where the package rounds to float32; C37.111's
missing-value codes as NaN). A 16-bit binary channel
stays 2 bytes a sample until the import asks for it. What the package would let through
silently is checked on the way: rows without the channel count the configuration declares,
records cut short, padding that is not the DOS end-of-file byte.
"""

from __future__ import annotations

import contextlib
import io
import itertools
import re
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import PhidError
from phid_ros.extras import require

CHUNK_ROWS = 65536
STAMP_MISSING = 0xFFFFFFFF
# stored type and missing-value code of each binary data file type (C37.111-1999/2013, as the
# ``comtrade`` package reads them; FLOAT32 has no code the package recognises)
BINARY_TYPES: dict[str, tuple[str, float | None]] = {
    "BINARY": ("<i2", -32768),
    "BINARY32": ("<i4", -(2**31)),
    "FLOAT32": ("<f4", None),
}
ASCII_MISSING = 99999.0  # C37.111-1999/2013; a 1991 file leaves the field blank
_CFF_HEADER = re.compile(rb"(?i)^--- file type: ([a-z]+)(?:\s+([a-z0-9]+)(?:\s*:\s*([0-9]+))?)? ---$")


class ComtradeImportError(PhidError):
    """A COMTRADE recording that is malformed or does not fit its channel map."""


@dataclass(frozen=True)
class DataSection:
    """Where a recording's samples are: a .dat file, or the DAT section of a .cff."""

    config: Path  # the .cfg (or the .cff itself), for the messages
    path: Path
    offset: int
    size: int | None  # bytes; None: to the end of the file (or, in a .cff, the next section)


@dataclass
class Samples:
    """The stamps and the asked-for analog channels of a recording, as stored."""

    source: Path
    stamps: NDArray[np.float64]  # in the stamps' unit (µs, or ns); NaN where missing
    stored: dict[int, np.ndarray]  # analog channel index (0-based) -> the stored values
    scale: dict[int, tuple[float, float]]  # index -> (a, b): value = a * stored + b
    missing: float | None  # the stored code of a missing value (ASCII and FLOAT32: already NaN)

    def __len__(self) -> int:
        return len(self.stamps)

    def values(self, index: int, rows: slice = slice(None)) -> NDArray[np.float64]:
        """Analog channel ``index`` in its .cfg unit (float, NaN where missing), in ``rows``."""
        x = self.stored[index][rows]
        a, b = self.scale[index]
        out = x * a + b if x.dtype == np.float64 else x.astype(np.float64) * a + b
        if self.missing is not None:
            out[x == self.missing] = np.nan
        return out


def _check_channel_count(lines: str, path: Path) -> None:
    """The .cfg's second line (``TT,##A,##D``) against the channel lines that follow it: a 6-line
    file declaring two billion channels had the parser build them until memory ran out."""
    rows = lines.splitlines()
    if len(rows) < 2:
        return  # the parser names what is missing
    counts = rows[1].split(",")
    try:
        total = int(counts[0].strip())
    except ValueError:
        return
    if total < 0 or total > len(rows) - 2:
        raise ComtradeImportError(
            f"{path}: declares {total} channels on its second line but has {len(rows) - 2} lines after it, "
            "one per channel: not a readable COMTRADE configuration"
        )
    try:
        analog, digital = (int(c.strip().rstrip("AaDd")) for c in counts[1:3])
    except ValueError:
        return
    if analog < 0 or digital < 0 or analog + digital != total:
        raise ComtradeImportError(
            f"{path}: its second line declares {analog} analog and {digital} status channels, "
            f"which is not the {total} channels it names first"
        )


def _cfg_from(lines: str, path: Path) -> Any:  # -> comtrade.Cfg
    comtrade = require("comtrade", "field", f"{path}: reading COMTRADE")
    _check_channel_count(lines, path)
    cfg = comtrade.Cfg(ignore_warnings=True)
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            cfg.read(lines)
    except (comtrade.ComtradeError, ValueError, IndexError, TypeError) as exc:
        raise ComtradeImportError(f"{path}: not a readable COMTRADE file ({exc})") from None
    return cfg


def open_recording(path: Path) -> tuple[Any, DataSection]:
    """(the parsed configuration, where its samples are) of a .cfg (with its .dat) or a .cff."""
    try:
        raw = path.read_bytes() if path.suffix.lower() != ".cff" else None
    except FileNotFoundError as exc:
        raise ComtradeImportError(f"{path}: {exc.strerror}: {exc.filename}") from None
    if raw is not None:
        cfg = _cfg_from(raw.decode("utf-8", errors="replace"), path)
        dat = next((path.with_suffix(s) for s in (".dat", ".DAT") if path.with_suffix(s).is_file()), None)
        if dat is None:
            raise ComtradeImportError(f"{path}: no .dat file beside it")
        return cfg, DataSection(path, dat, 0, None)
    return _open_cff(path)


def _open_cff(path: Path) -> tuple[Any, DataSection]:
    """The CFG section parsed, and the DAT section's place (C37.111-2013 §9: one file of sections)."""
    cfg_lines: list[str] = []
    section = b""
    try:
        fh = path.open("rb")
    except FileNotFoundError as exc:
        raise ComtradeImportError(f"{path}: {exc.strerror}: {exc.filename}") from None
    with fh:
        for line in iter(fh.readline, b""):
            head = _CFF_HEADER.match(line.strip())
            if head is not None:
                section = head.group(1).upper()
                if section == b"DAT":
                    size = int(head.group(3)) if head.group(3) else None
                    return _cfg_from("\n".join(cfg_lines), path), DataSection(path, path, fh.tell(), size)
            elif section == b"CFG":
                cfg_lines.append(line.decode("utf-8", errors="replace").strip())
    raise ComtradeImportError(f"{path}: no DAT section in the .cff")


def read_samples(cfg: Any, section: DataSection, wanted: Sequence[int], chunk_rows: int | None = None) -> Samples:
    """The stamps and the ``wanted`` analog channels (0-based indices) of a recording, read
    ``chunk_rows`` rows at a time (``CHUNK_ROWS``)."""
    chunk_rows = chunk_rows or CHUNK_ROWS
    ft = str(cfg.ft).strip().upper()
    a_b = {i: (float(cfg.analog_channels[i].a), float(cfg.analog_channels[i].b)) for i in wanted}
    if ft == "ASCII":
        stamps, stored = _read_ascii(cfg, section, wanted, chunk_rows)
        return Samples(section.path, stamps, stored, a_b, None)
    if ft not in BINARY_TYPES:
        raise ComtradeImportError(
            f"{section.path}: data file type {cfg.ft!r} not one of ASCII, {', '.join(BINARY_TYPES)}"
        )
    stamps, stored = _read_binary(cfg, section, ft, wanted, chunk_rows)
    return Samples(section.path, stamps, stored, a_b, BINARY_TYPES[ft][1])


def declared_rows(cfg: Any) -> int:
    """The last sample number the .cfg's rate lines state (0 when they state none)."""
    rates = cfg.sample_rates
    return int(rates[-1][1]) if rates else 0


def _read_binary(
    cfg: Any, section: DataSection, ft: str, wanted: Sequence[int], chunk_rows: int
) -> tuple[NDArray[np.float64], dict[int, np.ndarray]]:
    n_a, n_s = cfg.analog_count, cfg.status_count
    stored_type = BINARY_TYPES[ft][0]
    row = np.dtype([("n", "<u4"), ("t", "<u4"), ("a", stored_type, (n_a,)), ("s", "<u2", ((n_s + 15) // 16,))])
    with section.path.open("rb") as fh:
        end = fh.seek(0, io.SEEK_END)
        size = end - section.offset if section.size is None else min(section.size, end - section.offset)
        excess = size % row.itemsize
        if excess:
            fh.seek(section.offset + size - excess)
            if fh.read(excess) == b"\x1a" * excess:
                size -= excess  # DOS end-of-file padding after the last record (SEL relays write it)
            else:
                raise ComtradeImportError(
                    f"{section.path}: {size} bytes is not a whole number of {row.itemsize}-byte records for the "
                    f"{n_a} analog and {n_s} status channels {section.config.name} declares"
                )
        rows = size // row.itemsize
        declared = declared_rows(cfg)
        if declared:
            rows = min(rows, declared)  # what the .cfg says the recording holds, as the package reads it
        stamps = np.empty(rows, dtype=np.float64)
        stored = {i: np.empty(rows, dtype=stored_type) for i in wanted}
        fh.seek(section.offset)
        for start in range(0, rows, chunk_rows):
            block = np.fromfile(fh, dtype=row, count=min(chunk_rows, rows - start))
            stop = start + len(block)
            t = block["t"]
            stamps[start:stop] = np.where(t == STAMP_MISSING, np.nan, t)
            for i in wanted:
                stored[i][start:stop] = block["a"][:, i]
    return stamps, stored


def _ascii_lines(fh: BinaryIO, section: DataSection) -> Iterator[bytes]:
    """The data rows of an ASCII section (blank lines and the DOS end-of-file byte left out)."""
    for line in fh:
        s = line.strip()
        if section.path.suffix.lower() == ".cff" and s.startswith(b"--- file type"):
            return
        if s and s != b"\x1a":
            yield s


def _read_ascii(
    cfg: Any, section: DataSection, wanted: Sequence[int], chunk_rows: int
) -> tuple[NDArray[np.float64], dict[int, np.ndarray]]:
    n_a, n_s = cfg.analog_count, cfg.status_count
    width = 2 + n_a + n_s
    blank_missing = str(cfg.rev_year).strip() == "1991"
    columns = [1, *(2 + i for i in wanted)]
    parts: list[np.ndarray] = []
    with section.path.open("rb") as fh:
        fh.seek(section.offset)
        lines = _ascii_lines(fh, section)
        while chunk := list(itertools.islice(lines, chunk_rows)):
            counts = {line.count(b",") + 1 for line in chunk}
            if counts != {width}:
                raise ComtradeImportError(
                    f"{section.path}: rows carry {sorted(counts)} values but {section.config.name} declares "
                    f"{n_a} analog and {n_s} status channels ({width} values with sample number and time)"
                )
            parts.append(_parse_rows(chunk, columns, section.path, sum(len(x) for x in parts)))
    table = np.concatenate(parts) if parts else np.empty((0, len(columns)))
    del parts
    declared = declared_rows(cfg)
    if declared:
        table = table[:declared]
    stamps = np.ascontiguousarray(table[:, 0])
    stored = {}
    for k, i in enumerate(wanted, start=1):
        x = np.ascontiguousarray(table[:, k])
        if not blank_missing:
            x[x == ASCII_MISSING] = np.nan
        stored[i] = x
    return stamps, stored


def _parse_rows(chunk: list[bytes], columns: list[int], path: Path, first: int) -> np.ndarray:
    """The chosen columns of ASCII rows as numbers; a blank field (a non-critical stamp, a 1991
    missing value) as NaN."""
    try:
        return np.loadtxt(chunk, delimiter=",", usecols=columns, dtype=np.float64, ndmin=2, encoding="latin-1")
    except ValueError:
        pass  # a blank field somewhere in the chunk: the slow way, field by field
    out = np.empty((len(chunk), len(columns)))
    for r, line in enumerate(chunk):
        fields = line.split(b",")
        for k, c in enumerate(columns):
            text = fields[c].strip()
            try:
                out[r, k] = float(text) if text else np.nan
            except ValueError:
                raise ComtradeImportError(
                    f"{path}: data row {first + r + 1}, value {c + 1} is {text.decode(errors='replace')!r}, "
                    "not a number"
                ) from None
    return out
