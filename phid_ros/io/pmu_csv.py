"""PMU exports (one CSV row per report, as phasor data concentrators write them) -> scenarios.

A header row names the columns; one column is the report time (``time`` in the channel map,
default ``Timestamp``): seconds (a UNIX time or seconds from the start) or an ISO 8601 date
and time. The others are what the map names: phasor magnitude and angle (v_t, theta_t,
i_t, phi_i), P, Q, speed, rotor or load angle, field voltage, mechanical power. A PMU's
phasors are already filtered by the PMU: the map's ``machine.phasor_window_cycles`` (e.g. 2
for a P-class PMU) says over how many cycles, so stage 3 can leave that out around switching.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.io.channel_map import WAVEFORMS, ChannelMap, check_recording
from phid_ros.io.csv_import import is_number
from phid_ros.io.field_channels import field_recording, identification_channels, scenario_table
from phid_ros.io.recording import Recording
from phid_ros.model.conventions import NS

MAX_JITTER = 0.01  # of the reporting period: a clean export, taken as it is
# a step up to this much off the period is a jittered clock (a controller's trend log, +-0.3 ms at
# 208 samples/s), resampled onto the period; beyond it a report is missing (a gap, refused)
MAX_RESAMPLED_JITTER = 0.4


class PmuImportError(PhidError):
    """A PMU export that is malformed or does not fit its channel map."""


UNIX_SECONDS = 1e9  # seconds this large are UNIX time (2001 on), not seconds from the start


def _seconds(
    values: list[str], path: Path, column: str, dates: list[str] | None = None
) -> tuple[np.ndarray, int | None]:
    """Report times in s from the first, and when the first was taken (UTC ns since the epoch;
    None for times of day without a date and for seconds from the start): seconds, ISO 8601
    date-times, or (with ``dates``, a trend log's date column) times of day beside dates."""
    if dates is not None:
        values = [f"{_iso_date(d, path)}T{v.strip()}" for d, v in zip(dates, values)]
    elif values and all(_TIME_OF_DAY.fullmatch(v.strip()) for v in values):
        return _times_of_day(values), None
    if all(is_number(v) for v in values):  # seconds (UNIX or from the start); else ISO 8601 times
        secs = np.array([float(v) for v in values])
        return secs, int(round(secs[0] * NS)) if secs[0] >= UNIX_SECONDS else None
    try:
        stamps = np.array(
            [np.datetime64(_ns_digits(v.strip().replace("Z", ""))) for v in values], dtype="datetime64[ns]"
        )
    except ValueError as exc:
        raise PmuImportError(f"{path}: column {column!r} holds neither seconds nor ISO 8601 times ({exc})") from None
    return (stamps - stamps[0]).astype(np.int64) / NS, int(stamps[0].astype(np.int64))


_TIME_OF_DAY = re.compile(r"(\d{1,2}):(\d{2}):(\d{2}(?:\.\d+)?)")
_DATE = (
    (re.compile(r"(\d{4})-(\d{2})-(\d{2})"), (1, 2, 3)),  # ISO
    (re.compile(r"(\d{1,2})\.(\d{1,2})\.(\d{4})"), (3, 2, 1)),  # 20.09.2015, as European controllers write it
)


def _iso_date(text: str, path: Path) -> str:
    for pattern, (y, m, d) in _DATE:
        found = pattern.fullmatch(text.strip())
        if found:
            return f"{found[y]}-{int(found[m]):02d}-{int(found[d]):02d}"
    raise PmuImportError(f"{path}: date {text!r} is neither YYYY-MM-DD nor DD.MM.YYYY")


def _ns_digits(text: str) -> str:
    """At most nine fractional digits (a controller writes seven; numpy reads up to nanoseconds)."""
    return re.sub(r"(\.\d{9})\d+", r"\1", text)


def _times_of_day(values: list[str]) -> np.ndarray:
    """hh:mm:ss.fffffff without a date, in s from the first; a recording across midnight goes on."""
    secs = np.empty(len(values))
    for k, v in enumerate(values):
        found = _TIME_OF_DAY.fullmatch(v.strip())
        assert found is not None  # the caller matched every value
        secs[k] = int(found[1]) * 3600 + int(found[2]) * 60 + float(found[3])
    secs += 86400.0 * np.concatenate(([0], np.cumsum(np.diff(secs) < -43200.0)))
    return secs - secs[0]


def read_pmu_csv(
    path: str | Path, cmap: ChannelMap, notes: list[str] | None = None
) -> tuple[np.ndarray, dict[str, np.ndarray], float, int | None]:
    """(t from the first report, per-unit channels, the reporting rate, when the first report
    was taken if the file says: UTC ns); what was done to the reports (a jittered clock
    resampled) is added to ``notes``."""
    notes = notes if notes is not None else []
    p = Path(path)
    if not p.is_file():
        raise PmuImportError(f"{p}: no such PMU export")
    with p.open(newline="", encoding="utf-8-sig") as fh:
        first = fh.readline()
        fh.seek(0)
        # a decimal-comma locale's export: ';' between fields, 0,5 for 0.5
        euro = first.count(";") > first.count(",")
        rows = list(csv.reader(fh, delimiter=";" if euro else ","))
    if euro:
        rows = [[f.replace(",", ".") for f in r] for r in rows]
    if len(rows) < 3:
        raise PmuImportError(f"{p}: needs a header row and at least two reports")
    header = [h.strip() for h in rows[0]]
    columns = {h: i for i, h in enumerate(header)}
    if any(cmap.has(w) for w in WAVEFORMS):
        raise PmuImportError(f"{cmap.path}: a PMU export carries phasors, not waveforms ({', '.join(WAVEFORMS)})")
    time_col = cmap.time_column
    if time_col not in columns:
        raise PmuImportError(f"{p}: no time column {time_col!r} (map: time); columns: {', '.join(header)}")
    date_col = cmap.date_column
    if date_col is not None and date_col not in columns:
        raise PmuImportError(f"{p}: no date column {date_col!r} (map: date); columns: {', '.join(header)}")
    check_recording(cmap, p.name, [h for h in header if h not in (time_col, date_col)])
    body = rows[1:]
    ragged = next((k for k, r in enumerate(body) if len(r) != len(header)), None)
    if ragged is not None:
        raise PmuImportError(f"{p}: line {ragged + 2} has {len(body[ragged])} fields, the header {len(header)}")
    dates = [r[columns[date_col]] for r in body] if date_col is not None else None
    t, start_ns = _seconds([r[columns[time_col]] for r in body], p, time_col, dates)
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise PmuImportError(f"{p}: report times do not increase (line {k + 3}: {t[k + 1]:.6f} s after {t[k]:.6f} s)")
    period = float(np.median(dt))
    gap = np.flatnonzero(np.abs(dt - period) > MAX_RESAMPLED_JITTER * period)
    if gap.size:
        k = int(gap[0])
        raise PmuImportError(
            f"{p}: reports missing at line {k + 3}: {dt[k] * 1e3:.3f} ms after the previous, at "
            f"{t[k + 1]:.3f} s from the start (the rate is {1 / period:g} per s); export the event without gaps"
        )
    grid = None
    jitter = float(np.max(np.abs(dt - period)))
    if jitter > MAX_JITTER * period:
        period = (t[-1] - t[0]) / (len(t) - 1)  # the clock's mean period: the median of jittered steps is off
        # a jittered clock, nothing missing: the reports onto the mean period, linearly (the
        # channels are phasors and slow values, smooth at the report rate)
        grid = np.arange(0.0, t[-1] - t[0] + 0.5 * period, period)[: len(t)] + t[0]
        grid = grid[grid <= t[-1]]
        notes.append(
            f"{p.name}: report times jitter by up to {jitter * 1e3:.3f} ms around {period * 1e3:.3f} ms: "
            f"resampled onto {1 / period:.4g} per s by linear interpolation"
        )

    def recorded(name: str) -> np.ndarray:
        col = columns[name]
        try:
            x = np.array([float(r[col]) for r in body])
        except ValueError:
            k = next(k for k, r in enumerate(body) if not is_number(r[col]))
            raise PmuImportError(f"{p}: line {k + 2}, column {name!r}: {body[k][col]!r} is not a number") from None
        if not np.all(np.isfinite(x)):
            k = int(np.flatnonzero(~np.isfinite(x))[0])
            raise PmuImportError(f"{p}: line {k + 2}, column {name!r}: {body[k][col]!r} is not finite")
        return np.interp(grid, t, x) if grid is not None else x

    t_out, channels, _ = identification_channels(cmap, recorded, 1.0 / period, str(p))
    return t[0] + t_out, channels, 1.0 / period, start_ns


def import_pmu_csv(paths: Sequence[str | Path], cmap: ChannelMap) -> Recording:
    """Several exports -> one scenario set, one scenario per export (as ``import-csv`` makes)."""
    if not paths:
        raise PmuImportError("no PMU exports given")
    tables = []
    for path in paths:
        notes: list[str] = []
        t, channels, _, start_ns = read_pmu_csv(path, cmap, notes)
        table = scenario_table(Path(path), cmap, t - t[0], channels)
        table.notes = notes
        table.start_ns = start_ns
        tables.append(table)
    window = cmap.phasor_window_cycles / cmap.f_nominal_hz
    return field_recording(tables, cmap, f"import-pmu {cmap.path}", window)
