"""COMTRADE recordings (IEEE C37.111-1999/-2013: .cfg + ASCII/binary .dat, or one .cff) -> scenarios.

The configuration is parsed by the maintained ``comtrade`` package, the samples are read in
chunks, only the mapped channels (:mod:`phid_ros.io.field.comtrade_dat`); this module checks the
sample times (increasing, one rate, or the stamps a rate makes non-critical) and puts the
channels on a whole number of samples per cycle. The channel map
(:mod:`phid_ros.io.field.channel_map`) says which channel is which quantity; the conversion to the
identification's channels is :mod:`phid_ros.io.field.field_channels`.
"""

from __future__ import annotations

import calendar
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from phid_ros.io.csvset.csv_import import ScenarioTable
from phid_ros.io.field import comtrade_dat
from phid_ros.io.field.channel_map import WAVEFORMS, ChannelMap, ChannelMapError, choose_map, named_once, not_mapped
from phid_ros.io.field.comtrade_dat import ComtradeImportError, Samples, declared_rows, open_recording, read_samples
from phid_ros.io.field.field_channels import field_recording, identification_channels, scenario_table
from phid_ros.io.recording import Recording
from phid_ros.model.conventions import NS
from phid_ros.numerics import interpolant, uniform_grid

__all__ = ["ComtradeImportError", "import_comtrade", "read_comtrade", "unwrap_stamps"]


def _stamp_notes(path: Path, cfg, stamps: np.ndarray) -> list[str]:  # cfg: comtrade.Cfg
    """The stamps against the .cfg: with a rate they are non-critical (C37.111) and a note says
    when they disagree with it; without one they must increase."""
    if _rate_given(cfg):
        fs = max(float(r) for r, _ in cfg.sample_rates)
        step = 1.0 / (fs * cfg.time_base * cfg.timemult)  # in the stamps' unit (µs, or ns in a 2013 file)
        known = np.isfinite(stamps)
        if not known.any():
            return []
        k0 = int(np.argmax(known))
        on_rate, zero = True, True
        chunk = comtrade_dat.CHUNK_ROWS
        for s in range(k0, len(stamps), chunk):  # a chunk at a time: hours of stamps, no copies of them
            x = stamps[s : s + chunk]
            k = np.flatnonzero(np.isfinite(x))
            on_rate = on_rate and bool(np.all(np.abs(x[k] - stamps[k0] - (k + s - k0) * step) <= 0.5 * step))
            zero = zero and not np.any(x[k])
        if not on_rate:
            what = "all 0" if zero else "wrapped or uneven"
            return [
                f"{path.name}: sample times taken from the .cfg's rate ({fs:g} Hz); the stamps are {what} "
                "(non-critical by C37.111)"
            ]
        return []
    _check_times(path, unwrap_stamps(stamps))
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


def _sample_times(path: Path, cfg, samples: Samples) -> tuple[np.ndarray | None, float]:  # cfg: comtrade.Cfg
    """(each sample's time from the start in s, or None when they are ``1/rate`` apart; the rate).

    With a rate in the .cfg the times follow from it, whatever the stamps say (wrapped at 2^16
    µs, or all 0: non-critical by C37.111). Without one (``nrates`` 0: a frequency-tracking
    recorder) the stamps are the times, unwrapped.
    """
    rates = {float(r) for r, _ in cfg.sample_rates if float(r) > 0}
    if len(rates) > 1:
        raise ComtradeImportError(f"{path}: several sampling rates {sorted(rates)}; one rate is needed")
    if rates:
        return None, rates.pop()
    t = unwrap_stamps(samples.stamps) * (cfg.time_base * cfg.timemult)
    t = t - t[0] if t.size else t
    if t.size < 2 or not np.all(np.diff(t) > 0):
        raise ComtradeImportError(f"{path}: sample times do not increase")
    if np.ptp(np.diff(t)) <= 1e-3 * float(np.median(np.diff(t))):
        return None, 1.0 / float(np.median(np.diff(t)))
    return t, 1.0 / float(np.median(np.diff(t)))


def _on_cycle_grid(
    t: np.ndarray | None, n: int, fs: float, f0: float, notes: list[str], name: str
) -> tuple[np.ndarray, float] | None:
    """The uniform grid of a whole number of samples per cycle nearest ``fs``, when the ``n``
    samples are not on one already (an off-grid rate, 5760 Hz at 50 Hz; a frequency-tracking
    recorder's uneven steps ``t``; None: uniform): the one-cycle DFT needs whole cycles. None
    when they are on such a grid."""
    per_cycle = fs / f0
    if t is None and abs(per_cycle - round(per_cycle)) <= 1e-6 * per_cycle:
        return None
    end = (n - 1) / fs if t is None else t[-1]
    fs_new = math.ceil(per_cycle - 1e-9) * f0  # up, never down: no resolution is lost
    grid = uniform_grid(0.0, end, 1.0 / fs_new)
    # the spline's error bound (numerics.interpolant), the fourth derivative being w^4 times the wave
    err = 100 * 5 / 384 * (2 * math.pi * f0 / fs) ** 4
    how = "uneven steps" if t is not None else f"{per_cycle:.3f} samples per {f0:g} Hz cycle"
    notes.append(
        f"{name}: resampled from {how} to {fs_new:g} Hz ({round(fs_new / f0)} per cycle) by a cubic spline "
        f"(a waveform moves by at most {err:.2g} % of its amplitude)"
    )
    return grid, fs_new


def read_comtrade(path: str | Path, cmaps: ChannelMap | Sequence[ChannelMap]) -> ScenarioTable:
    """One recording -> one scenario table (per unit, synchronous frame); of several maps of one
    unit, through the one it fits (:func:`choose_map`)."""
    p = Path(path)
    cfg, section = open_recording(p)
    names = [str(ch.name).strip() for ch in cfg.analog_channels]
    cmap = choose_map([cmaps] if isinstance(cmaps, ChannelMap) else list(cmaps), p.name, names)
    named_once(str(p), names, cmap)
    columns = {n: i for i, n in enumerate(names)}
    samples = read_samples(cfg, section, sorted({columns[spec.name] for spec in cmap.channels.values()}))
    if not len(samples):
        raise ComtradeImportError(f"{section.path}: no samples")
    notes = _stamp_notes(p, cfg, samples.stamps)
    declared = declared_rows(cfg)
    if declared > len(samples):  # a .dat cut short (a copy interrupted, a disk full on the recorder)
        notes.append(
            f"{section.path.name}: holds {len(samples)} of the {declared} samples {p.name} declares "
            f"({100 * len(samples) / declared:.0f} %): the recording is cut short, imported up to the cut"
        )
    t_rec, fs = _sample_times(p, cfg, samples)
    waveforms = cmap.has(*WAVEFORMS[:3])
    regrid = _on_cycle_grid(t_rec, len(samples), fs, cmap.f_nominal_hz, notes, p.name) if waveforms else None
    if regrid is None and t_rec is not None:  # uneven phasor or value channels
        regrid = (np.arange(0.0, t_rec[-1], 1.0 / fs), fs)
        notes.append(f"{p.name}: resampled from uneven steps to {fs:g} Hz by a cubic spline")
    # the samples' times where they are resampled (a file on one grid keeps none)
    t_known = t_rec if t_rec is not None else np.arange(len(samples)) / fs if regrid is not None else np.empty(0)
    if regrid is not None:
        fs = regrid[1]

    splines: dict[str, Callable[[np.ndarray], np.ndarray]] = {}

    def recorded(name: str, rows: slice) -> np.ndarray:
        if regrid is None:
            return samples.values(columns[name], rows)
        if name not in splines:
            splines[name] = interpolant(t_known, samples.values(columns[name]), "cubic")
        return splines[name](regrid[0][rows])

    length = len(regrid[0]) if regrid is not None else len(samples)
    try:
        t, channels = identification_channels(cmap, recorded, length, fs, str(p))
    except ChannelMapError as exc:
        raise ComtradeImportError(str(exc)) from None
    table = scenario_table(p, cmap, t, channels)
    table.notes[:0] = notes
    table.not_imported = not_mapped(cmap, names)  # analog: a status bit is not a measurement lost
    table.start_ns = _start_ns(cfg.start_timestamp)
    return table


def _start_ns(when) -> int | None:  # when: datetime.datetime of the .cfg (naive: taken as UTC)
    if when is None or when.year <= 1900:  # the reader's stand-in for a missing date
        return None
    return calendar.timegm(when.timetuple()) * NS + when.microsecond * 1000


def import_comtrade(paths: Sequence[str | Path], cmaps: ChannelMap | Sequence[ChannelMap]) -> Recording:
    """Several recordings -> one scenario set, one scenario per recording (as ``import-csv`` makes)."""
    if not paths:
        raise ComtradeImportError("no COMTRADE recordings given")
    maps = [cmaps] if isinstance(cmaps, ChannelMap) else list(cmaps)
    tables = [read_comtrade(p, maps) for p in paths]
    # phasors of a one-cycle DFT when the voltage came as waveforms
    window = 1.0 / maps[0].f_nominal_hz if any(m.has(*WAVEFORMS[:3]) for m in maps) else 0.0
    return field_recording(tables, maps, f"import-comtrade {', '.join(m.path for m in maps)}", window)
