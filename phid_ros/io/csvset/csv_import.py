"""Import the CSV scenario set (the contract in docs/contracts.md: manifest.json + one CSV per scenario).

Columns ``t, v_t, theta_t, i_d, i_q, omega, delta, v_f, p_m, p_e, q_e`` (s, pu,
rad). The contract says extra columns are ignored; we report them (and with
``strict=True`` refuse them), and a missing column that looks like a misspelt
extra one is named in the error. Scenarios are placed one after another with a
recording gap between them: the CSV files are separate recordings, and we do
not invent data to join them.
"""

from __future__ import annotations

import csv
import difflib
import gzip
import hashlib
import io
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import CsvImportError
from phid_ros.io.files.results import read_json
from phid_ros.io.recording import (
    FIELD_BASES_KEY,
    MEASUREMENT_WINDOW_KEY,
    NOT_RECORDED_KEY,
    REGULATORS,
    Recording,
    ScenarioInfo,
    StreamSamples,
    field_bases,
)
from phid_ros.io.topics import RECORDER_CHANNELS, RECORDER_STREAMS, STREAMS
from phid_ros.model.channels import CHANNELS, SAME_PERIOD, unit_problem
from phid_ros.model.conventions import NS

CSV_COLUMNS: tuple[str, ...] = ("t",) + CHANNELS
# a recorder's own channels (the field current, the regulator's and stabiliser's outputs): read
# where a file has them, written where the recording kept them
OPTIONAL_COLUMNS: tuple[str, ...] = RECORDER_CHANNELS
KINDS = ("torque_step", "voltage_step", "fault", "field_step", "unknown")
ROLES = ("identify", "validate")
DEFAULT_START_NS = 1_767_225_600 * NS  # 2026-01-01T00:00:00Z
GAP_BETWEEN_SCENARIOS_S = 5.0
MAX_PERIOD_JITTER = 0.01  # relative
# one scenario's CSV as text: 30 s at 1 kHz is 3 MB; a gzip that inflates past this is refused
# rather than held (a 650 KB .csv.gz can inflate to tens of GB)
MAX_SCENARIO_CSV_BYTES = 1 << 30


@dataclass
class ScenarioTable:
    """One scenario as the importers read it: its own time axis (s) and the CSV channels on it."""

    name: str
    kind: str
    role: str
    generator_damping: bool
    t: NDArray[np.float64]
    columns: dict[str, NDArray[np.float64]]
    event_time_s: float | None = None  # on ``t``'s axis
    source: str = ""  # the file it came from, for messages
    notes: list[str] = field(default_factory=list)  # what the importer did to it (resampled, ...)
    start_ns: int | None = None  # when the file says it began (a COMTRADE .cfg's start time)
    regulator: str = ""  # who held the field: "avr", "manual" (io.recording.REGULATORS) or not said
    reference_step: float | None = None  # the test sheet's reference step, pu (+ and back)
    not_imported: list[str] = field(default_factory=list)  # the file's channels no map named


def _open_text(path: Path) -> TextIO:
    if path.name.endswith(".gz"):
        return io.TextIOWrapper(gzip.open(path, "rb"), encoding="utf-8-sig")
    return path.open("r", encoding="utf-8-sig", newline="")  # -sig: a spreadsheet's byte-order mark is not part of 't'


MAX_HEADER_CHARS = 1 << 16  # a header of a few thousand columns; one endless line is not a header


def read_header_line(path: Path, fh: TextIO) -> str:
    """The first line of a table, read with a bound: an endless first line was read whole and
    then refused by the csv module as "field larger than field limit"."""
    first = fh.readline(MAX_HEADER_CHARS + 1)
    if len(first) > MAX_HEADER_CHARS:
        raise CsvImportError(
            f"{path}: the first line runs past {MAX_HEADER_CHARS >> 10} KB without ending: not a header row"
        )
    return first


def _not_mostly_blank(path: Path, body: str, columns: int) -> None:
    """A body whose lines are mostly blank is refused before it is split: 0.65 MB of gzip inflated
    to 640 MB of newlines, and the list of its empty lines ran out of memory (14 GB). A row of
    ``columns`` numbers takes at least 2 ``columns`` characters; lines averaging less than half of
    that are more blank than rows."""
    lines = body.count("\n")
    if lines > 10_000 and lines * columns > len(body):
        raise CsvImportError(
            f"{path}: {lines} lines in {len(body) >> 20} MB of text, most of them blank (a compressed file that "
            "inflates to blank lines?): not a scenario table"
        )


def _read_bounded(path: Path, fh: TextIO) -> str:
    body = fh.read(MAX_SCENARIO_CSV_BYTES + 1)
    if len(body) > MAX_SCENARIO_CSV_BYTES:
        raise CsvImportError(
            f"{path}: more than {MAX_SCENARIO_CSV_BYTES >> 20} MB of text in one scenario "
            "(a compressed file that inflates without bound?); split the recording into scenarios"
        )
    return body


# a number in a decimal-comma locale: '.' groups thousands (802.637 is 802637), ',' is the point
_GROUPED = re.compile(r"[+-]?\d{1,3}(?:\.\d{3})+(?:,\d*)?(?:[eE][+-]?\d+)?")


def from_decimal_comma(text: str) -> str:
    """A decimal-comma locale's number as Python reads it: thousands points dropped, the comma a
    point. A point that does not group thousands (``1.5`` beside ``0,5``) is ambiguous: ValueError."""
    if "." in text:
        if not _GROUPED.fullmatch(text.strip()):
            raise ValueError(f"{text!r} has a point that does not group thousands in a decimal-comma file")
        text = text.replace(".", "")
    return text.replace(",", ".")


def decimal_comma_fields(fields: list[str]) -> tuple[list[str], int | None]:
    """:func:`from_decimal_comma` over a column's fields; the index of the first ambiguous one, or None."""
    if not any("." in f for f in fields):
        return [f.replace(",", ".") for f in fields], None
    out = []
    for k, f in enumerate(fields):
        try:
            out.append(from_decimal_comma(f))
        except ValueError:
            return out, k
    return out, None


def read_scenario_csv(path: Path, *, strict: bool = False) -> tuple[dict[str, NDArray[np.float64]], list[str]]:
    """Columns of one CSV as float arrays, checked; returns (columns, ignored extra columns)."""
    if not path.is_file():
        raise CsvImportError(f"{path}: no such CSV file")
    try:
        with _open_text(path) as fh:
            first = read_header_line(path, fh)
            body = _read_bounded(path, fh)
        if first.count(";") > first.count(","):
            # a spreadsheet in a decimal-comma locale: fields split by ';', 0,5 for 0.5, and a point
            # groups thousands (802.637 kW is 802637 kW: read as 802.637 it put P 1000x small)
            first, body = first.replace(";", ","), _decimal_comma_body(path, body)
        header = [h.strip() for h in next(csv.reader([first]), [])]
    except (OSError, EOFError, UnicodeDecodeError, gzip.BadGzipFile) as exc:
        raise CsvImportError(f"{path}: cannot read: {exc}") from exc
    if not header or header == [""]:
        raise CsvImportError(f"{path}: empty file, expected a header row")
    if len(set(header)) != len(header):
        dup = sorted({h for h in header if header.count(h) > 1})
        raise CsvImportError(f"{path}: duplicate column(s) {dup}")
    extra = [h for h in header if h not in CSV_COLUMNS and h not in OPTIONAL_COLUMNS]
    columns = CSV_COLUMNS + tuple(c for c in OPTIONAL_COLUMNS if c in header)
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        hints = []
        for m in missing:
            close = difflib.get_close_matches(m, extra, n=1, cutoff=0.6)
            hints.append(f"{m!r} (found {close[0]!r})" if close else repr(m))
        raise CsvImportError(f"{path}: missing column(s) {', '.join(hints)}; required: {', '.join(CSV_COLUMNS)}")
    if extra and strict:
        raise CsvImportError(f"{path}: unknown column(s) {extra}; allowed: {', '.join(CSV_COLUMNS)}")
    idx = [header.index(c) for c in columns]
    _not_mostly_blank(path, body, len(header))
    # loadtxt with usecols would accept a row with extra fields, shifting nothing but
    # hiding a broken export; check the field count of every line first (C-speed count)
    lines = body.splitlines()
    commas = np.fromiter((ln.count(",") for ln in lines), dtype=np.int64, count=len(lines))
    blank = np.fromiter((not ln.strip() for ln in lines), dtype=bool, count=len(lines))
    bad = np.flatnonzero((commas != len(header) - 1) & ~blank)
    if bad.size:
        r = int(bad[0])
        raise CsvImportError(f"{path}: line {r + 2} has {commas[r] + 1} fields, header has {len(header)}")
    try:
        data = np.loadtxt(io.StringIO(body), delimiter=",", usecols=idx, ndmin=2, dtype=float)
    except ValueError:
        _raise_parse_error(path, header, idx, body, columns)
    if data.shape[0] < 2:
        raise CsvImportError(f"{path}: needs at least two data rows, found {data.shape[0]}")
    finite = np.isfinite(data)
    # a channel NaN in every row was not recorded (phid writes a partial-channel import so: a trend
    # log has no i_d); the time and a channel with some values must be numbers throughout
    finite[:, 1:] |= np.isnan(data[:, 1:]).all(axis=0)
    if not finite.all():
        r, j = np.argwhere(~finite)[0]
        count = int((~finite.all(axis=1)).sum())
        raise CsvImportError(
            f"{path}: line {r + 2}, column {columns[j]!r} is {data[r, j]} "
            f"({count} row(s) with NaN/Inf); clean or drop them before import"
        )
    t = data[:, 0]
    dt = np.diff(t)
    if np.any(dt <= 0):
        r = int(np.flatnonzero(dt <= 0)[0])
        raise CsvImportError(f"{path}: time is not strictly increasing at line {r + 3} (t={t[r + 1]} after {t[r]})")
    period = float(np.median(dt))
    jitter = float(np.max(np.abs(dt - period)))
    if jitter > MAX_PERIOD_JITTER * period:
        raise CsvImportError(
            f"{path}: non-uniform sampling (period {period:g} s, deviation up to {jitter:g} s); "
            "resample to a uniform grid first"
        )
    return {c: data[:, j] for j, c in enumerate(columns)}, extra


def _decimal_comma_body(path: Path, body: str) -> str:
    """A ';'-separated body as a plain CSV's: where a field holds a comma the comma is the decimal
    mark and a point groups thousands; with no comma at all the points are decimal points."""
    if "," not in body:
        return body.replace(";", ",")
    if "." not in body:
        return body.replace(",", ".").replace(";", ",")
    lines = []
    for r, line in enumerate(body.splitlines()):
        fields, bad = decimal_comma_fields(line.split(";"))
        if bad is not None:
            raise CsvImportError(
                f"{path}: line {r + 2}, field {bad + 1}: {line.split(';')[bad]!r} has a point that does not group "
                "thousands in a decimal-comma file (';' between fields); write numbers as 802.637,5 or 802637,5"
            )
        lines.append(",".join(fields))
    return "\n".join(lines) + "\n"


def _raise_parse_error(path: Path, header: list[str], idx: list[int], body: str, columns: tuple[str, ...]) -> None:
    """Slow path, only after a parse failure: find the first bad line and say what is wrong."""
    for r, row in enumerate(csv.reader(io.StringIO(body))):
        if not row or not any(c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise CsvImportError(f"{path}: line {r + 2} has {len(row)} fields, header has {len(header)}")
        for j, i in enumerate(idx):
            if not is_number(row[i]):
                raise CsvImportError(f"{path}: line {r + 2}, column {columns[j]!r}: not a number ({row[i]!r})")
    raise CsvImportError(f"{path}: cannot parse as CSV of numbers")


def _scenario_name(path: Path) -> str:
    """The file's name without .csv or .csv.gz (a name may hold dots: ``S03_torque_+0.05.csv``)."""
    name = path.name
    for suffix in (".csv.gz", ".csv", ".gz"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return name


def is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def reference_step_of(value: Any, where: str) -> float | None:
    """A test sheet's ``reference_step`` (a map's or a manifest's): the size of a reference step,
    pu, positive and below 0.5 (a +5 % AVR step is 0.05; its return is the same step back)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 0.5:
        raise CsvImportError(
            f"{where}: reference_step must be the step's size in pu, above 0 and below 0.5, got {value!r}"
        )
    return float(value)


def _manifest_entry(entry: Any, k: int, manifest: Path) -> tuple[Path, str, str, bool, float | None, str]:
    where = f"{manifest}: scenarios[{k}]"
    if not isinstance(entry, dict) or "file" not in entry:
        raise CsvImportError(f"{where}: each scenario needs a 'file'")
    kind = entry.get("kind", "unknown")
    role = entry.get("role", "identify")
    damping = entry.get("generator_damping", True)
    if kind not in KINDS:
        raise CsvImportError(f"{where}: kind {kind!r} not one of {KINDS}")
    if role not in ROLES:
        raise CsvImportError(f"{where}: role {role!r} not one of {ROLES}")
    if not isinstance(damping, bool):
        raise CsvImportError(f"{where}: generator_damping must be true or false")
    regulator = entry.get("regulator", "")
    if regulator not in ("", *REGULATORS):
        raise CsvImportError(f"{where}: regulator {regulator!r} not one of {REGULATORS}")
    event = entry.get("event_time_s")
    if event is not None and (
        isinstance(event, bool) or not isinstance(event, (int, float)) or not math.isfinite(event)
    ):
        raise CsvImportError(f"{where}: event_time_s must be a number of seconds on the CSV's t axis, got {event!r}")
    name = str(entry["file"])
    folder = manifest.parent.resolve()
    path = (folder / name).resolve()
    if Path(name).is_absolute() or not path.is_relative_to(folder):
        raise CsvImportError(f"{where}: file {name!r} is outside the manifest's folder {folder}; refused")
    return manifest.parent / name, kind, role, damping, None if event is None else float(event), regulator


def import_csv_set(manifest_path: str | Path, *, strict: bool = False, start_ns: int = DEFAULT_START_NS) -> Recording:
    """Manifest -> one continuous recording, what the reading noticed (ignored columns) in its
    ``warnings``, as every importer returns it (:func:`phid_ros.api.import_recordings`)."""
    manifest = Path(manifest_path)
    try:
        meta = read_json(manifest)
    except Exception as exc:
        raise CsvImportError(str(exc)) from exc
    scenarios = meta.get("scenarios")
    if not isinstance(scenarios, list) or not scenarios:
        raise CsvImportError(f"{manifest}: 'scenarios' must be a non-empty list")
    f_nom = meta.get("f_nominal_hz", 50)
    if not isinstance(f_nom, (int, float)) or not math.isfinite(f_nom) or f_nom <= 0:
        raise CsvImportError(f"{manifest}: f_nominal_hz must be a positive number, got {f_nom!r}")
    base_mva = meta.get("base_mva")
    warnings: list[str] = []
    tables: list[ScenarioTable] = []
    for k, entry in enumerate(scenarios):
        path, kind, role, damping, event_s, regulator = _manifest_entry(entry, k, manifest)
        step = reference_step_of(entry.get("reference_step"), f"{manifest}: scenarios[{k}]")
        cols, extra = read_scenario_csv(path, strict=strict)
        if extra:
            warnings.append(f"{path}: ignored extra column(s) {extra}")
        t = cols.pop("t")
        if event_s is not None and not t[0] < event_s < t[-1]:
            raise CsvImportError(
                f"{manifest}: scenarios[{k}]: event_time_s {event_s:g} lies outside {path.name}'s "
                f"t = {t[0]:g} .. {t[-1]:g} s"
            )
        table = ScenarioTable(_scenario_name(path), kind, role, damping, t, cols, event_s, str(path))
        table.regulator, table.reference_step = regulator, step
        tables.append(table)
    rec = recording_from_tables(tables, float(f_nom), base_mva, f"import-csv {manifest.name}", start_ns=start_ns)
    window = meta.get(MEASUREMENT_WINDOW_KEY)
    if window is not None:
        if isinstance(window, bool) or not isinstance(window, (int, float)) or not 0 <= window < 1:
            raise CsvImportError(f"{manifest}: {MEASUREMENT_WINDOW_KEY} must be seconds in [0, 1), got {window!r}")
        rec.metadata[MEASUREMENT_WINDOW_KEY] = repr(float(window))
    bases = meta.get(FIELD_BASES_KEY)
    if bases is not None:
        if not isinstance(bases, str) or field_bases({FIELD_BASES_KEY: bases}) is None:
            raise CsvImportError(
                f"{manifest}: {FIELD_BASES_KEY} must read like 'v_f=74 V;i_fd=725 A' (positive numbers), got {bases!r}"
            )
        rec.metadata[FIELD_BASES_KEY] = bases
    rec.warnings.extend(warnings)
    return rec


def each_once(tables: Sequence[ScenarioTable]) -> None:
    """No recording is given twice: the same samples under a second name count one test twice
    (T'_d0 published with twice that test's weight, nothing said). Content, not names, decides.
    (A CSV set's manifest listing one file twice is counted once at the identification instead,
    said there: :func:`phid_ros.stream.scenarios.seen_before`.)"""
    seen: dict[str, ScenarioTable] = {}
    for tab in tables:
        h = hashlib.sha256(np.ascontiguousarray(tab.t, dtype=np.float64).tobytes())
        for c in sorted(tab.columns):
            h.update(c.encode() + b"\0" + np.ascontiguousarray(tab.columns[c], dtype=np.float64).tobytes())
        key = h.hexdigest()
        if key in seen:
            first = seen[key]
            raise CsvImportError(
                f"{tab.source or tab.name}: holds the same samples as {first.source or first.name}: one recording "
                "given twice would count its test twice; give it once"
            )
        seen[key] = tab


def _streams(
    tables: list[ScenarioTable],
    t_all: NDArray[np.int64],
    period_ns: int,
    c_parts: dict[str, list[NDArray[np.float64]]],
) -> dict[str, StreamSamples]:
    """The recording's streams on one clock: one scenario's columns become the streams' own (no
    copy: a 2 h recording's are 0.6 GB), and the streams share the clock, read-only."""
    t_all.flags.writeable = False
    streams = {
        spec.name: StreamSamples(
            t_all,
            period_ns,
            {c: c_parts[c][0] if len(tables) == 1 else np.concatenate(c_parts[c]) for c in spec.channels},
        )
        for spec in STREAMS
    }
    # a recorder's own channels (the field current, the regulator's and the stabiliser's outputs):
    # a stream of their own on the same clock, NaN in a file that did not keep one
    for spec in RECORDER_STREAMS:
        if any(c in tab.columns for tab in tables for c in spec.channels):
            streams[spec.name] = StreamSamples(
                t_all,
                period_ns,
                {
                    c: np.concatenate([tab.columns.get(c, np.full(len(tab.t), np.nan)) for tab in tables])
                    for c in spec.channels
                },
            )
    return streams


def recording_from_tables(
    tables: list[ScenarioTable],
    f_nominal_hz: float,
    base_mva: float | None,
    source: str,
    *,
    start_ns: int = DEFAULT_START_NS,
) -> Recording:
    """Scenario tables -> one continuous recording, one after another with a gap between them.

    The one place every importer (CSV sets, COMTRADE, PMU exports) turns its scenarios into
    the recording ``phid identify`` reads, so all give the same frames and markers.
    """
    t_parts: list[NDArray[np.int64]] = []
    c_parts: dict[str, list[NDArray[np.float64]]] = {c: [] for c in CHANNELS}
    infos: list[ScenarioInfo] = []
    period_ns: int | None = None
    cursor = start_ns
    for tab in tables:
        for c in CHANNELS:
            problem = unit_problem(c, tab.columns[c])
            if problem:
                raise CsvImportError(f"{tab.source}: {problem}")
        t = tab.t
        p_ns = int(round(float(np.median(np.diff(t))) * NS))
        if period_ns is None:
            period_ns = p_ns
        elif abs(p_ns - period_ns) > SAME_PERIOD * period_ns:  # a jittered clock's mean differs by ns
            raise CsvImportError(
                f"{tab.source}: sample period {p_ns} ns differs from the first scenario's {period_ns} ns "
                "(import the files of each rate apart; phid identify reads the recordings together)"
            )
        stamps = cursor + np.arange(len(t), dtype=np.int64) * period_ns
        event_ns = 0 if tab.event_time_s is None else int(stamps[0]) + int(round((tab.event_time_s - t[0]) * NS))
        t_parts.append(stamps)
        for c in CHANNELS:
            c_parts[c].append(tab.columns[c])
        infos.append(
            ScenarioInfo(
                name=tab.name,
                kind=tab.kind,
                role=tab.role,
                generator_damping=tab.generator_damping,
                start_ns=int(stamps[0]),
                event_ns=event_ns,
                end_ns=int(stamps[-1]),
                description=f"imported from {Path(tab.source).name}",
                regulator=tab.regulator,
                reference_step=tab.reference_step,
            )
        )
        cursor = int(stamps[-1]) + int(GAP_BETWEEN_SCENARIOS_S * NS)
    assert period_ns is not None
    streams = _streams(tables, np.concatenate(t_parts), period_ns, c_parts)
    metadata = {"f_nominal_hz": str(float(f_nominal_hz)), "source": source}
    if base_mva is not None:
        metadata["base_mva"] = str(base_mva)
    never = [c for c in CHANNELS if all(np.isnan(tab.columns[c]).all() for tab in tables)]
    if never:
        metadata[NOT_RECORDED_KEY] = ",".join(never)
    return Recording(streams=streams, scenarios=infos, metadata=metadata)
