"""COMTRADE recordings (IEEE C37.111-1999/-2013: .cfg + ASCII/binary .dat, or one .cff) -> scenarios.

The files are parsed by the maintained ``comtrade`` package; before that, this module checks
what the package would let through silently: a .dat whose rows do not carry the channel
count the .cfg declares, sample times that do not increase, several sampling rates. The
channel map (:mod:`phid_ros.io.channel_map`) says which channel is which quantity; the
conversion to the identification's channels is :mod:`phid_ros.io.field_channels`.
"""

from __future__ import annotations

import contextlib
import io
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.extras import require
from phid_ros.io.channel_map import WAVEFORMS, ChannelMap, ChannelMapError, check_recording
from phid_ros.io.csv_import import ScenarioTable
from phid_ros.io.field_channels import field_recording, identification_channels, scenario_table
from phid_ros.io.recording import Recording


class ComtradeImportError(PhidError):
    """A COMTRADE recording that is malformed or does not fit its channel map."""


def _load(path: Path, what: str = "recording"):  # -> comtrade.Comtrade, or comtrade.Cfg for "cfg"
    comtrade = require("comtrade", "field", f"{path}: reading COMTRADE")
    rec = comtrade.Cfg(ignore_warnings=True) if what == "cfg" else comtrade.Comtrade(ignore_warnings=True)
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            rec.load(str(path))
    except FileNotFoundError as exc:
        raise ComtradeImportError(f"{path}: {exc.strerror}: {exc.filename}") from None
    except (comtrade.ComtradeError, ValueError, IndexError, TypeError) as exc:
        raise ComtradeImportError(f"{path}: not a readable COMTRADE file ({exc})") from None
    return rec


def _check_dat(cfg_path: Path, cfg) -> None:  # cfg: comtrade.Cfg
    """The .dat against its .cfg (before the reader, which fails on it without saying why):
    values per row, whole records, increasing sample times."""
    n_a, n_s = cfg.analog_count, cfg.status_count
    dat = next((cfg_path.with_suffix(s) for s in (".dat", ".DAT") if cfg_path.with_suffix(s).is_file()), None)
    if dat is None:
        raise ComtradeImportError(f"{cfg_path}: no .dat file beside it")
    ft = cfg.ft.upper()
    if ft == "ASCII":
        with dat.open("r", encoding="utf-8", errors="replace") as fh:
            rows = [line.strip() for line in fh if line.strip() and line.strip() != "\x1a"]
        counts = {len(r.split(",")) for r in rows}
        if counts != {2 + n_a + n_s}:
            raise ComtradeImportError(
                f"{dat}: rows carry {sorted(counts)} values but {cfg_path.name} declares {n_a} analog and "
                f"{n_s} status channels ({2 + n_a + n_s} values with sample number and time)"
            )
        stamps = np.array([float(r.split(",")[1] or "nan") for r in rows])
    else:
        width = {"BINARY": 2, "BINARY32": 4, "FLOAT32": 4}.get(ft)
        if width is None:
            raise ComtradeImportError(
                f"{cfg_path}: data file type {cfg.ft!r} not one of ASCII, BINARY, BINARY32, FLOAT32"
            )
        size = 8 + width * n_a + 2 * ((n_s + 15) // 16)
        raw = dat.read_bytes()
        if len(raw) % size:
            raise ComtradeImportError(
                f"{dat}: {len(raw)} bytes is not a whole number of {size}-byte records for the "
                f"{n_a} analog and {n_s} status channels {cfg_path.name} declares"
            )
        stamps = np.ndarray((len(raw) // size,), dtype="<u4", buffer=raw, offset=4, strides=(size,))
        stamps = np.where(stamps == 0xFFFFFFFF, np.nan, stamps.astype(float))
    _check_times(cfg_path, stamps)


def _check_times(path: Path, stamps: np.ndarray) -> None:
    known = stamps[np.isfinite(stamps)]
    if known.size > 1 and np.any(np.diff(known) <= 0):
        k = int(np.flatnonzero(np.diff(known) <= 0)[0])
        raise ComtradeImportError(
            f"{path}: sample times do not increase (sample {k + 2}: {known[k + 1]:g} after {known[k]:g})"
        )


def _sample_rate(path: Path, rec) -> float:
    rates = {float(r) for r, _ in rec.cfg.sample_rates if float(r) > 0}
    if len(rates) > 1:
        raise ComtradeImportError(f"{path}: several sampling rates {sorted(rates)}; one rate is needed")
    t = np.asarray(rec.time, dtype=float)
    if t.size < 2 or np.any(np.diff(t) <= 0):
        raise ComtradeImportError(f"{path}: sample times do not increase")
    return rates.pop() if rates else 1.0 / float(np.median(np.diff(t)))


def read_comtrade(path: str | Path, cmap: ChannelMap) -> ScenarioTable:
    """One recording -> one scenario table (per unit, synchronous frame)."""
    p = Path(path)
    if p.suffix.lower() == ".cfg":
        _check_dat(p, _load(p, "cfg"))
    rec = _load(p)
    fs = _sample_rate(p, rec)
    names = [str(n).strip() for n in rec.analog_channel_ids]
    columns = {n: i for i, n in enumerate(names)}
    check_recording(cmap, p.name, names)
    analog = rec.analog

    def recorded(name: str) -> np.ndarray:
        return np.asarray(analog[columns[name]], dtype=float)

    try:
        t, channels, f_sys = identification_channels(cmap, recorded, fs, str(p))
    except ChannelMapError as exc:
        raise ComtradeImportError(str(exc)) from None
    return scenario_table(p, cmap, t, channels)


def import_comtrade(paths: Sequence[str | Path], cmap: ChannelMap) -> Recording:
    """Several recordings -> one scenario set, one scenario per recording (as ``import-csv`` makes)."""
    if not paths:
        raise ComtradeImportError("no COMTRADE recordings given")
    tables = [read_comtrade(p, cmap) for p in paths]
    # phasors of a one-cycle DFT when the voltage came as waveforms
    window = 1.0 / cmap.f_nominal_hz if cmap.has(*WAVEFORMS[:3]) else 0.0
    return field_recording(tables, cmap, f"import-comtrade {cmap.path}", window)
