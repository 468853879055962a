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
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.io.channel_map import WAVEFORMS, ChannelMap, check_recording
from phid_ros.io.csv_import import is_number
from phid_ros.io.field_channels import field_recording, identification_channels, scenario_table
from phid_ros.io.recording import Recording
from phid_ros.model.conventions import NS

MAX_JITTER = 0.01  # of the reporting period


class PmuImportError(PhidError):
    """A PMU export that is malformed or does not fit its channel map."""


def _seconds(values: list[str], path: Path, column: str) -> np.ndarray:
    if all(is_number(v) for v in values):  # seconds (UNIX or from the start); else ISO 8601 times
        return np.array([float(v) for v in values])
    try:
        stamps = np.array([np.datetime64(v.strip().replace("Z", "")) for v in values], dtype="datetime64[ns]")
    except ValueError as exc:
        raise PmuImportError(f"{path}: column {column!r} holds neither seconds nor ISO 8601 times ({exc})") from None
    return (stamps - stamps[0]).astype(np.int64) / NS


def read_pmu_csv(path: str | Path, cmap: ChannelMap) -> tuple[np.ndarray, dict[str, np.ndarray], float]:
    """(t from the first report, per-unit channels, the reporting rate)."""
    p = Path(path)
    if not p.is_file():
        raise PmuImportError(f"{p}: no such PMU export")
    with p.open(newline="", encoding="utf-8-sig") as fh:
        rows = list(csv.reader(fh))
    if len(rows) < 3:
        raise PmuImportError(f"{p}: needs a header row and at least two reports")
    header = [h.strip() for h in rows[0]]
    columns = {h: i for i, h in enumerate(header)}
    if any(cmap.has(w) for w in WAVEFORMS):
        raise PmuImportError(f"{cmap.path}: a PMU export carries phasors, not waveforms ({', '.join(WAVEFORMS)})")
    time_col = cmap.time_column
    if time_col not in columns:
        raise PmuImportError(f"{p}: no time column {time_col!r} (map: time); columns: {', '.join(header)}")
    check_recording(cmap, p.name, [h for h in header if h != time_col])
    body = rows[1:]
    ragged = next((k for k, r in enumerate(body) if len(r) != len(header)), None)
    if ragged is not None:
        raise PmuImportError(f"{p}: line {ragged + 2} has {len(body[ragged])} fields, the header {len(header)}")
    t = _seconds([r[columns[time_col]] for r in body], p, time_col)
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise PmuImportError(f"{p}: report times do not increase (line {k + 3}: {t[k + 1]:.6f} s after {t[k]:.6f} s)")
    period = float(np.median(dt))
    off = np.flatnonzero(np.abs(dt - period) > MAX_JITTER * period)
    if off.size:
        k = int(off[0])
        raise PmuImportError(
            f"{p}: reports missing or uneven at line {k + 3} ({dt[k] * 1e3:.3f} ms after the previous, "
            f"the rate is {1 / period:g} per s); export the event without gaps"
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
        return x

    t_out, channels, _ = identification_channels(cmap, recorded, 1.0 / period, str(p))
    return t[0] + t_out, channels, 1.0 / period


def import_pmu_csv(paths: Sequence[str | Path], cmap: ChannelMap) -> Recording:
    """Several exports -> one scenario set, one scenario per export (as ``import-csv`` makes)."""
    if not paths:
        raise PmuImportError("no PMU exports given")
    tables = []
    for path in paths:
        t, channels, _ = read_pmu_csv(path, cmap)
        tables.append(scenario_table(Path(path), cmap, t - t[0], channels))
    window = cmap.phasor_window_cycles / cmap.f_nominal_hz
    return field_recording(tables, cmap, f"import-pmu {cmap.path}", window)
