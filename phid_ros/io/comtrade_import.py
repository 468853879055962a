"""COMTRADE recordings (IEEE C37.111-1999/-2013: .cfg + ASCII/binary .dat, or one .cff) -> scenarios.

The files are parsed by the maintained ``comtrade`` package; before that, this module checks
what the package would let through silently: a .dat whose rows do not carry the channel
count the .cfg declares, sample times that do not increase, several sampling rates. The
channel map (:mod:`phid_ros.io.channel_map`) says which channel is which quantity; the
conversion to the identification's channels is :mod:`phid_ros.io.field_channels`.
"""

from __future__ import annotations

import calendar
import contextlib
import io
import math
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from phid_ros.errors import PhidError
from phid_ros.extras import require
from phid_ros.io.channel_map import WAVEFORMS, ChannelMap, ChannelMapError, check_recording
from phid_ros.io.csv_import import ScenarioTable
from phid_ros.io.field_channels import field_recording, identification_channels, scenario_table
from phid_ros.io.recording import Recording
from phid_ros.model.conventions import NS


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


def _check_dat(cfg_path: Path, cfg) -> list[str]:  # cfg: comtrade.Cfg
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
        excess = len(raw) % size
        if excess and raw[-excess:] == b"\x1a" * excess:
            raw = raw[:-excess]  # DOS end-of-file padding after the last record (SEL relays write it)
        if len(raw) % size:
            raise ComtradeImportError(
                f"{dat}: {len(raw)} bytes is not a whole number of {size}-byte records for the "
                f"{n_a} analog and {n_s} status channels {cfg_path.name} declares"
            )
        stamps = np.ndarray((len(raw) // size,), dtype="<u4", buffer=raw, offset=4, strides=(size,))
        stamps = np.where(stamps == 0xFFFFFFFF, np.nan, stamps.astype(float))
    if _rate_given(cfg):  # the times come from the rate; C37.111 calls the stamps non-critical then
        fs = max(float(r) for r, _ in cfg.sample_rates)
        step = 1.0 / (fs * cfg.time_base * cfg.timemult)  # in the stamps' unit (µs, or ns in a 2013 file)
        known = np.isfinite(stamps)
        k = np.flatnonzero(known)
        if k.size and not np.allclose(stamps[k] - stamps[k[0]], (k - k[0]) * step, rtol=0, atol=0.5 * step):
            what = "all 0" if not np.any(stamps[k]) else "wrapped or uneven"
            return [
                f"{cfg_path.name}: sample times taken from the .cfg's rate ({fs:g} Hz); the stamps are {what} "
                "(non-critical by C37.111)"
            ]
        return []
    _check_times(cfg_path, unwrap_stamps(stamps))
    return []


def _rate_given(cfg) -> bool:  # cfg: comtrade.Cfg
    """Whether the .cfg states a sampling rate (then the sample times follow from it)."""
    return any(float(r) > 0 for r, _ in cfg.sample_rates)


def unwrap_stamps(stamps: np.ndarray) -> np.ndarray:
    """Stamps of a counter that wrapped (at 2^16 or 2^32 time units) made increasing again."""
    out = np.asarray(stamps, dtype=float).copy()
    ok = np.isfinite(out)
    for bits in (16, 32):
        top = float(1 << bits)
        if np.nanmax(out, initial=0.0) < top:
            d = np.diff(out[ok])
            back = d < -0.5 * top
            if back.any():
                out[ok] += np.concatenate(([0.0], np.cumsum(back) * top))
                break
    return out


def _check_times(path: Path, stamps: np.ndarray) -> None:
    known = stamps[np.isfinite(stamps)]
    if known.size and not np.any(known):
        raise ComtradeImportError(f"{path}: every sample time is 0 and the .cfg states no sampling rate")
    if known.size > 1 and np.any(np.diff(known) <= 0):
        k = int(np.flatnonzero(np.diff(known) <= 0)[0])
        raise ComtradeImportError(
            f"{path}: sample times do not increase (sample {k + 2}: {known[k + 1]:g} after {known[k]:g})"
        )


def _sample_times(path: Path, rec, notes: list[str]) -> tuple[np.ndarray, float]:
    """Each sample's time from the start (s) and the rate.

    With a rate in the .cfg the times follow from it, whatever the stamps say (wrapped at 2^16
    µs, or all 0: non-critical by C37.111), and a note says so when they disagree. Without one
    (``nrates`` 0: a frequency-tracking recorder) the stamps are the times, unwrapped.
    """
    rates = {float(r) for r, _ in rec.cfg.sample_rates if float(r) > 0}
    if len(rates) > 1:
        raise ComtradeImportError(f"{path}: several sampling rates {sorted(rates)}; one rate is needed")
    n = len(rec.analog[0]) if rec.analog else 0
    if rates:
        fs = rates.pop()
        t = np.arange(n, dtype=np.float64) / fs
        return t, fs
    # the stamps as recorded (the reader scales them, and does not unwrap a counter that wrapped)
    unit = rec.cfg.time_base * rec.cfg.timemult
    t = unwrap_stamps(np.asarray(rec.time, dtype=float) / unit) * unit
    t = t - t[0] if t.size else t
    if t.size < 2 or np.any(np.diff(t) <= 0):
        raise ComtradeImportError(f"{path}: sample times do not increase")
    return t, 1.0 / float(np.median(np.diff(t)))


def _on_cycle_grid(t: np.ndarray, fs: float, f0: float, notes: list[str], name: str) -> tuple[np.ndarray, float] | None:
    """The uniform grid of a whole number of samples per cycle nearest ``fs``, when ``t`` is not
    one already (an off-grid rate, 5760 Hz at 50 Hz; a frequency-tracking recorder's uneven
    steps): the one-cycle DFT needs whole cycles. None when ``t`` is on such a grid."""
    per_cycle = fs / f0
    uniform = t.size < 3 or np.ptp(np.diff(t)) <= 1e-3 / fs
    if uniform and abs(per_cycle - round(per_cycle)) <= 1e-6 * per_cycle:
        return None
    fs_new = math.ceil(per_cycle - 1e-9) * f0  # up, never down: no resolution is lost
    grid = np.arange(0.0, t[-1] + 0.5 / fs_new, 1.0 / fs_new)
    grid = grid[grid <= t[-1]]
    # a cubic spline through samples h apart misses a sinusoid of angular frequency w by at most
    # 5/384 (w h)^4 of its amplitude (the spline's error bound; the fourth derivative is w^4 times it)
    err = 100 * 5 / 384 * (2 * math.pi * f0 / fs) ** 4
    how = "uneven steps" if not uniform else f"{per_cycle:.3f} samples per {f0:g} Hz cycle"
    notes.append(
        f"{name}: resampled from {how} to {fs_new:g} Hz ({round(fs_new / f0)} per cycle) by a cubic spline "
        f"(a waveform moves by at most {err:.2g} % of its amplitude)"
    )
    return grid, fs_new


def read_comtrade(path: str | Path, cmap: ChannelMap) -> ScenarioTable:
    """One recording -> one scenario table (per unit, synchronous frame)."""
    p = Path(path)
    notes = _check_dat(p, _load(p, "cfg")) if p.suffix.lower() == ".cfg" else []
    rec = _load(p)
    t_rec, fs = _sample_times(p, rec, notes)
    names = [str(n).strip() for n in rec.analog_channel_ids]
    columns = {n: i for i, n in enumerate(names)}
    check_recording(cmap, p.name, names)
    analog = rec.analog
    regrid = _on_cycle_grid(t_rec, fs, cmap.f_nominal_hz, notes, p.name) if cmap.has(*WAVEFORMS[:3]) else None
    if regrid is None and np.ptp(np.diff(t_rec)) > 1e-3 / fs:  # uneven phasor or value channels
        regrid = (np.arange(0.0, t_rec[-1], 1.0 / fs), fs)
        notes.append(f"{p.name}: resampled from uneven steps to {fs:g} Hz by a cubic spline")
    if regrid is not None:
        fs = regrid[1]

    def recorded(name: str) -> np.ndarray:
        x = np.asarray(analog[columns[name]], dtype=float)
        return CubicSpline(t_rec, x)(regrid[0]) if regrid is not None else x

    try:
        t, channels, f_sys = identification_channels(cmap, recorded, fs, str(p))
    except ChannelMapError as exc:
        raise ComtradeImportError(str(exc)) from None
    table = scenario_table(p, cmap, t, channels)
    table.notes = notes
    table.start_ns = _start_ns(rec.cfg.start_timestamp)
    return table


def _start_ns(when) -> int | None:  # when: datetime.datetime of the .cfg (naive: taken as UTC)
    if when is None or when.year <= 1900:  # the reader's stand-in for a missing date
        return None
    return calendar.timegm(when.timetuple()) * NS + when.microsecond * 1000


def import_comtrade(paths: Sequence[str | Path], cmap: ChannelMap) -> Recording:
    """Several recordings -> one scenario set, one scenario per recording (as ``import-csv`` makes)."""
    if not paths:
        raise ComtradeImportError("no COMTRADE recordings given")
    tables = [read_comtrade(p, cmap) for p in paths]
    # phasors of a one-cycle DFT when the voltage came as waveforms
    window = 1.0 / cmap.f_nominal_hz if cmap.has(*WAVEFORMS[:3]) else 0.0
    return field_recording(tables, cmap, f"import-comtrade {cmap.path}", window)
