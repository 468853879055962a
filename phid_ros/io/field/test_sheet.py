"""A machine's steady-state test sheet: the open-circuit and short-circuit curves of IEEE 115.

A commissioning or laboratory test records each curve as a small table, one row per point: the
field current and the terminal voltage (open circuit) or the armature current (short circuit).
The sheet (YAML) names the tables, their columns, and the voltage and armature current that are
1 pu::

    rated: {v: 127.017, i_a: 5.25}    # V as the OCC's column reads it (per phase or line to line), A
    occ: {file: occ.csv, i_f: i_f_A, v: v_avg_V}
    scc: {file: scc.csv, i_f: i_f_A, i_a: i_avg_A}

Files are found beside the sheet. Tables are CSV with ``,`` or ``;`` between fields (decimal
commas with ``;``); the field current stays in amperes (its base is what the curves determine).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import PhidError
from phid_ros.io.csvset.csv_import import decimal_comma_fields, is_number
from phid_ros.io.files.yaml_doc import load_yaml

Array = NDArray[np.float64]
MAX_TABLE_BYTES = 10 * 2**20  # a test's curve is tens of points, not megabytes


class SheetError(PhidError):
    """A test sheet or one of its tables that cannot be read, named with the file and the field."""


@dataclass
class Curve:
    """One measured curve: the field current (A) against V_t or I_a (pu), with its table's name."""

    i_f: Array
    x: Array
    source: str


@dataclass
class TestSheet:
    path: str
    occ: Curve  # I_f against the terminal voltage, pu
    scc: Curve  # I_f against the armature current, pu
    rated_v: float
    rated_i_a: float


def load_test_sheet(path: str | Path) -> TestSheet:
    p = Path(path)
    doc = load_yaml(p)
    if not isinstance(doc, dict):
        raise SheetError(f"{p}: a test sheet is a mapping with rated, occ and scc")
    rated = _section(doc, "rated", p)
    v, i_a = (_positive(rated, k, f"{p}: rated.{k}") for k in ("v", "i_a"))
    occ = _curve(_section(doc, "occ", p), "v", v, p)
    scc = _curve(_section(doc, "scc", p), "i_a", i_a, p)
    return TestSheet(str(p), occ, scc, v, i_a)


def _section(doc: dict[str, Any], key: str, p: Path) -> dict[str, Any]:
    value = doc.get(key)
    if not isinstance(value, dict):
        raise SheetError(f"{p}: {key}: missing or not a mapping")
    return value


def _positive(doc: dict[str, Any], key: str, where: str) -> float:
    value = doc.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise SheetError(f"{where}: must be a positive number, got {value!r}")
    return float(value)


def _curve(section: dict[str, Any], x_key: str, rated: float, sheet: Path) -> Curve:
    which = "occ" if x_key == "v" else "scc"
    name = section.get("file")
    if not isinstance(name, str):
        raise SheetError(f"{sheet}: {which}.file: missing")
    table = (sheet.parent / name) if not Path(name).is_absolute() else Path(name)
    columns = {k: section.get(k) for k in ("i_f", x_key)}
    for k, col in columns.items():
        if not isinstance(col, str):
            raise SheetError(f"{sheet}: {which}.{k}: the column's name is missing")
    data = read_table(table, [str(c) for c in columns.values()])
    i_f, x = data[str(columns["i_f"])], data[str(columns[x_key])] / rated
    order = np.argsort(x)
    if len(x) < 3:
        raise SheetError(f"{table}: {len(x)} point(s); a curve needs at least 3")
    if np.any(i_f <= 0) or np.any(x <= 0):
        raise SheetError(f"{table}: a point with zero or negative current or voltage")
    return Curve(i_f[order], x[order], str(table))


def read_table(path: Path, columns: list[str]) -> dict[str, Array]:
    """The named numeric columns of a small CSV (``,`` or ``;``; decimal commas beside ``;``)."""
    if not path.is_file():
        raise SheetError(f"{path}: no such table")
    if path.stat().st_size > MAX_TABLE_BYTES:
        raise SheetError(f"{path}: larger than {MAX_TABLE_BYTES >> 20} MB: not a test curve")
    text = path.read_text(encoding="utf-8-sig", errors="replace")
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if len(lines) < 2:
        raise SheetError(f"{path}: needs a header row and points")
    delimiter = ";" if lines[0].count(";") > lines[0].count(",") else ","
    rows = list(csv.reader(lines, delimiter=delimiter))
    header = [h.strip() for h in rows[0]]
    # a ';' table with a comma anywhere writes decimal commas (a point then groups thousands);
    # one without keeps its points as decimal points
    comma_decimals = delimiter == ";" and any("," in f for r in rows[1:] for f in r)
    out: dict[str, Array] = {}
    for col in columns:
        if col not in header:
            raise SheetError(f"{path}: no column {col!r} (columns: {', '.join(header)})")
        j = header.index(col)
        fields = [r[j].strip() if j < len(r) else "" for r in rows[1:]]
        if comma_decimals:
            fields, bad = decimal_comma_fields(fields)
            if bad is not None:
                raise SheetError(f"{path}: line {bad + 2}, column {col!r}: a point that groups nothing")
        try:
            out[col] = np.array([float(f) for f in fields])
        except ValueError:
            k = next(i for i, f in enumerate(fields) if not is_number(f))
            raise SheetError(f"{path}: line {k + 2}, column {col!r}: {fields[k]!r} is not a number") from None
        nonfinite = np.flatnonzero(~np.isfinite(out[col]))
        if nonfinite.size:  # 'nan' and 'inf' read as numbers, and reached scipy's spline as a traceback
            k = int(nonfinite[0])
            raise SheetError(f"{path}: line {k + 2}, column {col!r}: {fields[k]!r} is not a finite number")
    return out
