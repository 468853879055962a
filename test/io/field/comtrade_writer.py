"""A small COMTRADE writer for the tests (the importer's reader is the ``comtrade`` package).

.cfg + ASCII or BINARY .dat (C37.111-1999 or -2013), or one .cff (2013). Each analog channel
is stored as 16-bit integers with its own scale a (value = a * stored).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _cfg(
    channels: dict[str, tuple[np.ndarray, str]],
    n: int,
    fs: float,
    f_line: float,
    rev: str,
    ft: str,
    start: str = "01/01/2026,00:00:00.000000",
) -> tuple[str, dict]:
    lines = [f"PHID TEST,SIMULATOR,{rev}", f"{len(channels)},{len(channels)}A,0D"]
    scales = {}
    for k, (name, (x, unit)) in enumerate(channels.items(), start=1):
        a = max(float(np.max(np.abs(x))), 1e-12) / 32000.0
        scales[name] = a
        lines.append(f"{k},{name},,,{unit},{a:.12g},0,0,-32767,32767,1,1,P")
    # fs 0: no rate (nrates 0, a frequency-tracking recorder): the stamps are the times
    rates = ["0", f"0,{n}"] if fs == 0 else ["1", f"{fs:g},{n}"]
    lines += [f"{f_line:g}", *rates, start, start, ft, "1"]
    if rev == "2013":
        lines += ["+0h00,+0h00", "0,0"]
    return "\r\n".join(lines) + "\r\n", scales


def _rows(channels: dict[str, tuple[np.ndarray, str]], scales: dict, fs: float) -> np.ndarray:
    return np.column_stack([np.round(x / scales[name]).astype(np.int16) for name, (x, _) in channels.items()])


def write_comtrade(
    path: Path,
    channels: dict[str, tuple[np.ndarray, str]],
    fs: float,
    *,
    f_line: float = 50.0,
    rev: str = "1999",
    ft: str = "ASCII",
    stamps: np.ndarray | None = None,
    start: str = "01/01/2026,00:00:00.000000",
    declare_rate: bool = True,
    pad: int = 0,
) -> Path:
    """``path`` ending in .cfg (with its .dat) or .cff; ``channels``: name -> (values, unit).

    A recorder's habits, as C37.111 allows them: ``stamps`` (µs) instead of the rate's (wrapped,
    all 0, uneven), no rate in the .cfg (``declare_rate`` False: nrates 0), ``pad`` 0x1A bytes
    after a binary .dat's last record, the .cfg's ``start`` date and time.
    """
    n = len(next(iter(channels.values()))[0])
    cfg, scales = _cfg(channels, n, fs if declare_rate else 0.0, f_line, rev, ft, start)
    data = _rows(channels, scales, fs)
    if stamps is None:
        stamps = np.round(np.arange(n) * 1e6 / fs).astype(np.int64)
    if ft == "ASCII":
        body = (
            "\r\n".join(
                f"{k + 1},{stamps[k]}," + ",".join(map(str, row)) for k, row in enumerate(data.tolist())
            ).encode()
            + b"\r\n"
        )
    else:
        rec = np.zeros(n, dtype=[("n", "<u4"), ("t", "<u4"), ("a", "<i2", (data.shape[1],))])
        rec["n"], rec["t"], rec["a"] = np.arange(1, n + 1), stamps, data
        body = rec.tobytes() + b"\x1a" * pad
    if path.suffix.lower() == ".cff":
        head = "--- file type: CFG ---\r\n" + cfg
        dat = f"--- file type: DAT {ft}" + (f": {len(body)}" if ft != "ASCII" else "") + " ---\r\n"
        path.write_bytes(head.encode() + dat.encode() + body)
    else:
        path.write_text(cfg, newline="")
        path.with_suffix(".dat").write_bytes(body)
    return path
