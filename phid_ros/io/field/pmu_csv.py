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
import itertools
import re
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.io.csvset.csv_import import ScenarioTable, decimal_comma_fields, is_number, read_header_line
from phid_ros.io.field.channel_map import (
    PULSES,
    WAVEFORMS,
    ChannelMap,
    check_recording,
    choose_map,
    named_once,
    not_mapped,
)
from phid_ros.io.field.field_channels import field_recording, identification_channels, scenario_table
from phid_ros.io.recording import Recording
from phid_ros.model.conventions import NS
from phid_ros.numerics import interpolant, uniform_grid

MAX_JITTER = 0.01  # of the reporting period: a clean export, taken as it is
# a step up to this much off the period is a jittered clock (a controller's trend log, +-0.3 ms at
# 208 samples/s), resampled onto the period; beyond it a report is missing (a gap, refused)
MAX_RESAMPLED_JITTER = 0.4
# A polled log (a laptop reading a controller over Telnet: 0.12-0.69 s between rows, median
# 0.15 s) has no period to be off: its intervals spread by more than POLLED_SPREAD of their median
# (5th to 95th percentile). It is read on its own stamps, and a report is missing only where an
# interval exceeds POLLED_GAP times the median (1.2 s at 0.15 s: a field time constant of seconds
# is still seen).
POLLED_SPREAD = 0.2
POLLED_GAP = 8.0
# a channel repeating its last value on this share of consecutive reports, for stretches of
# HELD_REPORTS or more, is sampled and held by the source (refreshed slower than it is polled)
HELD_SHARE = 0.3
HELD_REPORTS = 5


class PmuImportError(PhidError):
    """A PMU export that is malformed or does not fit its channel map."""


UNIX_SECONDS = 1e9  # seconds this large are UNIX time (2001 on), not seconds from the start
# reports parsed at a time: a day's export (4.3 million reports at 50/s) was held as Python strings
# whole, 3 GB and more; now only the mapped columns, as numbers
CHUNK_ROWS = 65_536

_ONE_DIGIT_HOUR = re.compile(r"([T ])(\d):")  # 2026-11-26 9:00:00: numpy wants 09
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


def _padded_time(text: str) -> str:
    """A time of day as ISO 8601 writes it (9:00:00.0000000 -> 09:00:00.0000000), else as given."""
    found = _TIME_OF_DAY.fullmatch(text.strip())
    return f"{int(found[1]):02d}:{found[2]}:{found[3]}" if found else text.strip()


def _ns_digits(text: str) -> str:
    """At most nine fractional digits (a controller writes seven; numpy reads up to nanoseconds)."""
    return re.sub(r"(\.\d{9})\d+", r"\1", text)


class _Clock:
    """The time column, read a chunk at a time in the form its first reports have: seconds (UNIX
    or from the start), times of day, ISO 8601 date-times, or (with a date column, a trend log's)
    times of day beside dates."""

    def __init__(self, path: Path, column: str, first: list[str], dated: bool) -> None:
        self.path, self.column = path, column
        if dated:
            self.form = "dated"
        elif all(_TIME_OF_DAY.fullmatch(v.strip()) for v in first):
            self.form = "time of day"
        elif all(is_number(v) for v in first):
            self.form = "seconds"
        else:
            self.form = "iso"
        self._parts: list[np.ndarray] = []

    def add(self, values: list[str], dates: list[str] | None, line: int) -> None:
        """One chunk's times; ``line`` is the file's line of its first report."""
        try:
            self._parts.append(self._parse(values, dates))
        except (ValueError, AssertionError):
            k = next(k for k in range(len(values)) if not self._fits(values[k], dates[k] if dates else None))
            raise PmuImportError(
                f"{self.path}: line {line + k}, column {self.column!r}: {values[k]!r} is not a time "
                f"({'a time of day beside a date' if self.form == 'dated' else self.form}, as the first reports)"
            ) from None

    def _fits(self, value: str, date: str | None) -> bool:
        try:
            self._parse([value], [date] if date is not None else None)
        except (ValueError, AssertionError):
            return False
        return True

    def _parse(self, values: list[str], dates: list[str] | None) -> np.ndarray:
        if self.form == "seconds":
            return np.array([float(v) for v in values])
        if self.form == "time of day":
            secs = np.empty(len(values))
            for k, v in enumerate(values):
                found = _TIME_OF_DAY.fullmatch(v.strip())
                assert found is not None
                secs[k] = int(found[1]) * 3600 + int(found[2]) * 60 + float(found[3])
            return secs
        if dates is not None:
            values = [f"{_iso_date(d, self.path)}T{_padded_time(v)}" for d, v in zip(dates, values)]
        return np.array(
            [np.datetime64(_ns_digits(_ONE_DIGIT_HOUR.sub(r"\g<1>0\2:", v.strip().replace("Z", "")))) for v in values],
            dtype="datetime64[ns]",
        )

    def seconds(self) -> tuple[np.ndarray, int | None]:
        """Report times in s (from the first, or UNIX seconds as written), and when the first was
        taken (UTC ns since the epoch; None for times of day without a date and for seconds from
        the start)."""
        x = np.concatenate(self._parts)
        if self.form == "seconds":
            return x, int(round(x[0] * NS)) if x[0] >= UNIX_SECONDS else None
        if self.form == "time of day":  # a recording across midnight goes on
            x = x + 86400.0 * np.concatenate(([0], np.cumsum(np.diff(x) < -43200.0)))
            return x - x[0], None
        return (x - x[0]).astype(np.int64) / NS, int(x[0].astype(np.int64))


class _Column:
    """A mapped column as numbers, chunk by chunk; the first entry that is not a finite number is
    remembered (line and text) and reported when the column is used, after the time checks."""

    def __init__(self) -> None:
        self.parts: list[np.ndarray] = []
        self.bad: tuple[int, str, str] | None = None  # (line, text, "not a number" | "not finite")

    def add(self, values: list[str], line: int) -> None:
        try:
            x = np.array([float(v) for v in values])
        except ValueError:
            x = np.array([float(v) if is_number(v) else np.nan for v in values])
            k = next(k for k, v in enumerate(values) if not is_number(v))
            self._note(line + k, values[k], "is not a number")
        bad = ~np.isfinite(x)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            self._note(line + k, values[k], "is not finite")
        self.parts.append(x)

    def _note(self, line: int, text: str, what: str) -> None:
        if self.bad is None or line < self.bad[0]:
            self.bad = (line, text, what)


def _chunk(path: Path, reader: Iterator[list[str]], line: int) -> list[list[str]]:
    """The next :data:`CHUNK_ROWS` rows; a field beyond the csv module's limit (an endless line)
    is a one-line error naming where, not ``_csv.Error``."""
    rows: list[list[str]] = []
    try:
        rows.extend(itertools.islice(reader, CHUNK_ROWS))
    except csv.Error as exc:
        raise PmuImportError(f"{path}: line {line + len(rows)}: {exc} (an endless line?)") from None
    return rows


def _read_columns(
    path: Path,
    fh: TextIO,
    delimiter: str,
    euro: bool,
    header: list[str],
    clock_col: str,
    date_col: str | None,
    wanted: list[str],
) -> tuple[_Clock, dict[str, _Column]]:
    """The body of the export, ``CHUNK_ROWS`` reports at a time: the time (and date) column and
    the ``wanted`` ones, as numbers; every line checked for its number of fields."""
    columns = {h: i for i, h in enumerate(header)}
    reader = csv.reader(fh, delimiter=delimiter)
    clock: _Clock | None = None
    out = {name: _Column() for name in wanted}
    line = 2  # the file's line of the chunk's first report
    comma: bool | None = None  # ';' fields: is the comma the decimal mark? (the first reports say)
    while chunk := _chunk(path, reader, line):
        ragged = next((k for k, r in enumerate(chunk) if len(r) != len(header)), None)
        if ragged is not None:
            raise PmuImportError(
                f"{path}: line {line + ragged} has {len(chunk[ragged])} fields, the header {len(header)}"
            )
        if euro:
            has_comma = next(((k, n) for n in wanted for k, r in enumerate(chunk) if "," in r[columns[n]]), None)
            if comma is None:
                comma = has_comma is not None
            elif not comma and has_comma is not None:
                k, n = has_comma
                raise PmuImportError(
                    f"{path}: line {line + k}, column {n!r}: {chunk[k][columns[n]]!r} has a decimal comma where "
                    "the reports before it have none: one decimal mark per export"
                )

        def field(name: str) -> list[str]:
            i = columns[name]
            values = [r[i] for r in chunk]
            if not comma:  # ',' fields, or ';' fields with decimal points
                return values
            # a point groups thousands here (802.637 kW is 802637 kW; read as 802.637 it put P 1000x small)
            values, bad = decimal_comma_fields(values)
            if bad is not None:
                raise PmuImportError(
                    f"{path}: line {line + bad}, column {name!r}: {chunk[bad][i]!r} has a point that does not group "
                    "thousands in a decimal-comma export (';' between fields)"
                )
            return values

        times = [r[columns[clock_col]].replace(",", ".") for r in chunk] if euro else field(clock_col)
        dates = [r[columns[date_col]] for r in chunk] if date_col is not None else None
        if clock is None:
            clock = _Clock(path, clock_col, times, dated=dates is not None)
        clock.add(times, dates, line)
        for name, col in out.items():
            col.add(field(name), line)
        line += len(chunk)
    if clock is None or line < 4:
        raise PmuImportError(f"{path}: needs a header row and at least two reports")
    return clock, out


def read_pmu_csv(path: str | Path, cmaps: ChannelMap | Sequence[ChannelMap]) -> ScenarioTable:
    """One export -> one scenario table (per unit, t from its first report), as every reader of a
    field recording gives it (:func:`phid_ros.io.field.comtrade_import.read_comtrade`): what was
    done to the reports in its ``notes``, the columns the map names for nothing in its
    ``not_imported``, when the first report was taken (UTC ns) in its ``start_ns`` where the file
    says; of several maps of one unit, through the one it fits (:func:`choose_map`)."""
    notes: list[str] = []
    skipped: list[str] = []
    t, channels, _, start_ns, cmap = _read_reports(path, cmaps, notes, skipped)
    table = scenario_table(Path(path), cmap, t - t[0], channels)
    table.notes[:0] = notes
    table.not_imported = skipped
    table.start_ns = start_ns
    return table


def _read_reports(
    path: str | Path,
    cmaps: ChannelMap | Sequence[ChannelMap],
    notes: list[str] | None = None,
    skipped: list[str] | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray], float, int | None, ChannelMap]:
    """(t from the first report, per-unit channels, the reporting rate, when the first report
    was taken if the file says: UTC ns, the map it was read through: of several maps of one
    unit, :func:`choose_map`'s); what was done to the reports (a jittered clock resampled) is
    added to ``notes``, the columns the map names for nothing to ``skipped``. The file is read a
    chunk of reports at a time."""
    maps = [cmaps] if isinstance(cmaps, ChannelMap) else list(cmaps)
    cmap = maps[0]
    notes = notes if notes is not None else []
    p = Path(path)
    if not p.is_file():
        raise PmuImportError(f"{p}: no such PMU export")
    with p.open(newline="", encoding="utf-8-sig") as fh:
        first = read_header_line(p, fh)
        # a decimal-comma locale's export: ';' between fields, 0,5 for 0.5
        euro = first.count(";") > first.count(",")
        delimiter = ";" if euro else ","
        header = [h.strip() for h in next(csv.reader([first], delimiter=delimiter), [])]
        if not header or not fh.readline():
            raise PmuImportError(f"{p}: needs a header row and at least two reports")
        fh.seek(0)
        fh.readline()
        columns = {h: i for i, h in enumerate(header)}
        if len(maps) > 1:
            cmap = choose_map(maps, p.name, header)
        if any(cmap.has(w) for w in WAVEFORMS):
            raise PmuImportError(f"{cmap.path}: a PMU export carries phasors, not waveforms ({', '.join(WAVEFORMS)})")
        time_col = cmap.time_column
        if time_col not in columns:
            raise PmuImportError(f"{p}: no time column {time_col!r} (map: time); columns: {', '.join(header)}")
        date_col = cmap.date_column
        if date_col is not None and date_col not in columns:
            raise PmuImportError(f"{p}: no date column {date_col!r} (map: date); columns: {', '.join(header)}")
        named_once(str(p), header, cmap)
        read = check_recording(cmap, p.name, [h for h in header if h not in (time_col, date_col)])
        chosen = next((m for m in maps if m.path == cmap.path), cmap)
        mapped = chosen.channels  # as the map names them
        if skipped is not None:
            skipped.extend(not_mapped(chosen, header))
        left = [f"{q} ({spec.name})" for q, spec in mapped.items() if q not in read.channels]
        if left:
            notes.append(f"{p.name}: no {', '.join(left)} in this file: imported without it")
        cmap = read
        wanted = sorted({c.name for c in cmap.channels.values() if c.name in columns})
        clock, values = _read_columns(p, fh, delimiter, euro, header, time_col, date_col, wanted)
    t, start_ns = clock.seconds()
    period, grid, polled = _report_grid(p, t, notes)

    def recorded(name: str, rows: slice) -> np.ndarray:
        col = values[name]
        if col.bad is not None:
            line, text, what = col.bad
            raise PmuImportError(f"{p}: line {line}, column {name!r}: {text!r} {what}")
        if len(col.parts) > 1:
            col.parts = [np.concatenate(col.parts)]  # the chunks let go: a day's column is held once, not twice
        x = col.parts[0]
        return interpolant(t, x)(grid[rows]) if grid is not None else x[rows]

    if polled:
        notes.extend(_polled_channel_notes(p.name, t, cmap, values))
    length = len(grid) if grid is not None else len(t)
    t_out, channels = identification_channels(cmap, recorded, length, 1.0 / period, str(p))
    return t[0] + t_out, channels, 1.0 / period, start_ns, cmap


def _report_grid(p: Path, t: np.ndarray, notes: list[str]) -> tuple[float, np.ndarray | None, bool]:
    """(the reporting period, the uniform grid the reports are interpolated onto or None where
    they are on one already, whether the file is a polled log) from the reports' stamps ``t``;
    refused where reports are missing (a polled log's rule: an interval beyond ``POLLED_GAP`` x
    its median). What was done is added to ``notes``."""
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise PmuImportError(f"{p}: report times do not increase (line {k + 3}: {t[k + 1]:.6f} s after {t[k]:.6f} s)")
    period = float(np.median(dt))
    polled = float(np.percentile(dt, 95) - np.percentile(dt, 5)) > POLLED_SPREAD * period
    gap = np.flatnonzero(dt > POLLED_GAP * period if polled else np.abs(dt - period) > MAX_RESAMPLED_JITTER * period)
    if gap.size:
        k = int(gap[0])
        rule = (
            f"a polled log's interval beyond {POLLED_GAP:g} x its median {period:.3f} s"
            if polled
            else f"the rate is {1 / period:g} per s"
        )
        raise PmuImportError(
            f"{p}: reports missing at line {k + 3}: {dt[k] * 1e3:.3f} ms after the previous, at "
            f"{t[k + 1]:.3f} s from the start ({rule}); export the event without gaps"
        )
    grid = None
    jitter = float(np.max(np.abs(dt - period)))
    if jitter > MAX_JITTER * period:
        if polled:  # the median to two figures: the polled logs of one source share their grid
            period = float(f"{period:.2g}")
            grid = uniform_grid(t[0], t[-1], period)
        else:
            period = (t[-1] - t[0]) / (len(t) - 1)  # the clock's mean period: the median of jittered steps is off
            grid = uniform_grid(t[0], t[-1], period)[: len(t)]
        # a jittered clock (or a polled log), nothing missing: the reports onto the grid, linearly
        # (the channels are phasors and slow values, smooth at the report rate)
        if polled:
            notes.append(
                f"{p.name}: a polled log (intervals {dt.min():.3f}-{dt.max():.3f} s, median {np.median(dt):.3f} s; "
                f"a gap would be one beyond {POLLED_GAP:g} x the median): read on its own stamps and interpolated "
                f"linearly onto {1 / period:.4g} per s"
            )
        else:
            notes.append(
                f"{p.name}: report times jitter by up to {jitter * 1e3:.3f} ms around {period * 1e3:.3f} ms: "
                f"resampled onto {1 / period:.4g} per s by linear interpolation"
            )
    return period, grid, polled


def _polled_channel_notes(name: str, t: np.ndarray, cmap: ChannelMap, values: dict[str, _Column]) -> list[str]:
    """What a polled log's channels are worth between their reports: each mapped channel's
    linear-interpolation error (a report against the line through its two neighbours, the largest
    and in the channel's own units), and the channels the source samples and holds (the same value
    repeated for stretches of reports: its changes are timed to the source's refresh, not the poll)."""
    errors, held = [], []
    for q, spec in cmap.channels.items():
        col = values.get(spec.name)
        if col is None or col.bad is not None or not col.parts or q in PULSES:
            continue  # a command is on or off: held between changes by what it is, not by the source
        x = np.concatenate(col.parts) if len(col.parts) > 1 else col.parts[0]
        if len(x) < 3:
            continue
        w = (t[1:-1] - t[:-2]) / (t[2:] - t[:-2])
        between = x[:-2] + w * (x[2:] - x[:-2])
        errors.append(f"{q} {float(np.max(np.abs(x[1:-1] - between))):.3g} {spec.unit}")
        same = np.diff(x) == 0
        if same.mean() > HELD_SHARE:
            runs = np.diff(np.flatnonzero(np.concatenate(([True], ~same, [True]))))
            longest = int(runs.max())
            if longest >= HELD_REPORTS:
                held.append(f"{q} ({spec.name}: the same value on {100 * same.mean():.0f} % of consecutive reports)")
    out = [
        f"{name}: between polled reports, a report lies within "
        + ", ".join(errors)
        + " of the line through its neighbours (the largest: what linear interpolation misses at twice the interval)"
    ]
    if held:
        out.append(
            f"{name}: sampled and held by the source, refreshed slower than polled: {'; '.join(held)}: "
            "their changes are timed to the refresh"
        )
    return out


def import_pmu_csv(paths: Sequence[str | Path], cmaps: ChannelMap | Sequence[ChannelMap]) -> Recording:
    """Several exports -> one scenario set, one scenario per export (as ``import-csv`` makes);
    with several maps of one unit (no-load, on-line), each export through the one it fits."""
    if not paths:
        raise PmuImportError("no PMU exports given")
    maps = [cmaps] if isinstance(cmaps, ChannelMap) else list(cmaps)
    tables = [read_pmu_csv(path, maps) for path in paths]
    head = maps[0]
    window = head.phasor_window_cycles / head.f_nominal_hz
    return field_recording(tables, maps, f"import-pmu {', '.join(m.path for m in maps)}", window)
