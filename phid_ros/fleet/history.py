"""The parameter history of a fleet: one SQLite row per (unit, recording, phid version).

Only the process that runs ``phid fleet`` writes (tasks return rows, they do not open the
database), one row per finished task in its own transaction, so an interrupted run keeps every
row it finished and a rerun skips them. WAL lets ``phid history`` read while a run writes.
"""

from __future__ import annotations

import json
import math
import sqlite3
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, fields
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from phid_ros.errors import PhidError
from phid_ros.io.files.sqlite_schema import check_intact, migrate, table_columns
from phid_ros.model.parameters import PARAMETER_NAMES, SYMBOLS

DRIFT_SIGMAS = 4.0  # a change between consecutive well-identified sets beyond this many σ is flagged
STATUSES = ("ok", "failed")


class HistoryError(PhidError):
    """The history database cannot be used."""


@dataclass
class Row:
    """One task's outcome: the identified set, or the one-line reason it failed."""

    unit: str
    recording: str
    content_hash: str
    status: str
    phid_version: str
    start_ns: int | None = None
    end_ns: int | None = None
    values: dict[str, float] = field(default_factory=dict)
    stds: dict[str, float] = field(default_factory=dict)
    identifiable: dict[str, bool] = field(default_factory=dict)
    flags: list[str] = field(default_factory=list)  # notes of the identification (e.g. one steady state)
    effects: list[dict[str, Any]] = field(default_factory=list)  # named by the diagnosis, with parameters
    controls: dict[str, Any] = field(default_factory=dict)  # the exciter and governor, as identify's JSON
    method: str = ""
    wall_s: float = math.nan
    error: str = ""
    worker: str = ""
    finished_utc: str = ""
    method_version: str = ""  # phid_ros.provenance.method_version() of the code that made the row
    # the unit's record on file (its .dyr) played into each event of the recording, as phid
    # validate plays it: the record's path and content, and one verdict per event (Verdict.as_json)
    record: str = ""
    record_hash: str = ""
    verdicts: list[dict[str, Any]] = field(default_factory=list)
    design: str = ""  # the units of one design (sister units) share it: the inventory's key

    def well_identified(self, name: str) -> bool:
        v, s = self.values.get(name, math.nan), self.stds.get(name, math.nan)
        return (
            self.status == "ok"
            and bool(self.identifiable.get(name))
            and math.isfinite(v)
            and math.isfinite(s)
            and s > 0
        )


ADDED_COLUMNS = ("method_version", "record", "record_hash", "design")  # by schema steps after the first
_DOCUMENTS = ("flags", "effects", "controls", "verdicts")  # JSON columns
_SCALARS = [f.name for f in fields(Row) if f.name not in ("values", "stds", "identifiable", *_DOCUMENTS)]
_PARAM_COLUMNS = [c for n in PARAMETER_NAMES for c in (n, f"{n}_std", f"{n}_identifiable")]
_COLUMNS = _SCALARS + _PARAM_COLUMNS + list(_DOCUMENTS)


def _create_sql() -> str:
    """Version 1 of the runs table (frozen: later columns come by their own steps)."""
    types = {"start_ns": "INTEGER", "end_ns": "INTEGER", "wall_s": "REAL"}
    cols = [f"{c} {types.get(c, 'TEXT')}" for c in _SCALARS if c not in ADDED_COLUMNS]
    cols += [f"{c} {'INTEGER' if c.endswith('_identifiable') else 'REAL'}" for c in _PARAM_COLUMNS]
    cols += ["flags TEXT", "effects TEXT"]
    return (
        "CREATE TABLE IF NOT EXISTS runs (id INTEGER PRIMARY KEY AUTOINCREMENT, "
        + ", ".join(cols)
        + ", UNIQUE (unit, content_hash, phid_version))"
    )


# the history's schema, step by step (io/files/sqlite_schema.py)
SCHEMA_STEPS = (
    _create_sql()
    + "; CREATE INDEX IF NOT EXISTS runs_unit ON runs (unit, start_ns)"
    + "; CREATE TABLE IF NOT EXISTS hash_cache (path TEXT PRIMARY KEY, stat_key TEXT, sha256 TEXT)",
    # 2: the method version, so that a rerun redoes what an older method identified
    "ALTER TABLE runs ADD COLUMN method_version TEXT NOT NULL DEFAULT ''",
    # 3: the exciter and governor identify names (a fleet identified units without their controls)
    "ALTER TABLE runs ADD COLUMN controls TEXT NOT NULL DEFAULT '{}'",
    # 4: the record on file checked at each event, and the design sister units share
    "ALTER TABLE runs ADD COLUMN record TEXT NOT NULL DEFAULT ''"
    "; ALTER TABLE runs ADD COLUMN record_hash TEXT NOT NULL DEFAULT ''"
    "; ALTER TABLE runs ADD COLUMN verdicts TEXT NOT NULL DEFAULT '[]'"
    "; ALTER TABLE runs ADD COLUMN design TEXT NOT NULL DEFAULT ''",
)


def _legacy_version(db: sqlite3.Connection) -> int:
    """A history from before ``user_version`` kept its schema in a meta table (1 was the only one)."""
    if not table_columns(db, "meta"):
        return 0
    found = db.execute("SELECT value FROM meta WHERE key='schema'").fetchone()
    return int(found[0]) if found is not None else 0


class History:
    """``FLEET_DIR/history.sqlite``."""

    def __init__(self, path: str | Path, *, create: bool = True) -> None:
        self.path = Path(path)
        if not create and not self.path.exists():
            raise HistoryError(f"{self.path}: no fleet history here (run phid fleet ... --out {self.path.parent})")
        try:
            self.db = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
            self.db.execute("PRAGMA journal_mode=WAL")
            self.db.execute("PRAGMA busy_timeout=30000")
            check_intact(
                self.db,
                f"{self.path}: fleet history",
                HistoryError,
                f"move it away (mv {self.path} {self.path}.damaged) and rerun phid fleet: it identifies the "
                "recordings again into a new history",
            )
            self._migrate()
        except sqlite3.DatabaseError as exc:
            raise HistoryError(f"{self.path}: not a usable fleet history ({exc})") from None

    def _migrate(self) -> None:
        migrate(self.db, SCHEMA_STEPS, what=f"{self.path}: fleet history", error=HistoryError, legacy=_legacy_version)

    def close(self) -> None:
        self.db.close()

    def __enter__(self) -> History:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- what is done ---------------------------------------------------------------------
    def done(self, unit: str, content_hash: str, method: str, record_hash: str = "") -> bool:
        """Whether this recording of this unit has a row made by this method version, checked
        against this record on file (``""``: none): a record given or changed is played again."""
        q = "SELECT 1 FROM runs WHERE unit=? AND content_hash=? AND method_version=? AND record_hash=?"
        return self.db.execute(q, (unit, content_hash, method, record_hash)).fetchone() is not None

    def failed(self, unit: str, content_hash: str, method: str) -> bool:
        q = "SELECT 1 FROM runs WHERE unit=? AND content_hash=? AND method_version=? AND status='failed'"
        return self.db.execute(q, (unit, content_hash, method)).fetchone() is not None

    def done_before(self, unit: str, content_hash: str) -> bool:
        """Whether some method version, any, has a row for this recording of this unit."""
        q = "SELECT 1 FROM runs WHERE unit=? AND content_hash=?"
        return self.db.execute(q, (unit, content_hash)).fetchone() is not None

    def cached_hash(self, path: Path, stat_key: str) -> str | None:
        found = self.db.execute("SELECT stat_key, sha256 FROM hash_cache WHERE path=?", (str(path),)).fetchone()
        return found[1] if found and found[0] == stat_key else None

    def cache_hash(self, path: Path, stat_key: str, sha256: str) -> None:
        self.db.execute("INSERT OR REPLACE INTO hash_cache VALUES (?, ?, ?)", (str(path), stat_key, sha256))

    # -- rows -----------------------------------------------------------------------------
    def add(self, row: Row) -> None:
        """Store one outcome; a rerun's row (``--retry-failed``) replaces the failure it retried."""
        if row.status not in STATUSES:
            raise ValueError(f"status {row.status!r}")
        row.finished_utc = row.finished_utc or datetime.now(timezone.utc).isoformat(timespec="seconds")
        values: list[Any] = [getattr(row, c) for c in _SCALARS]
        for n in PARAMETER_NAMES:
            values += [_real(row.values.get(n)), _real(row.stds.get(n)), int(bool(row.identifiable.get(n)))]
        values += [json.dumps(getattr(row, d)) for d in _DOCUMENTS]
        marks = ", ".join("?" * len(_COLUMNS))
        try:
            self.db.execute(f"INSERT OR REPLACE INTO runs ({', '.join(_COLUMNS)}) VALUES ({marks})", values)
        except sqlite3.OperationalError as exc:  # a full disk, a read-only folder, a lock held too long
            raise HistoryError(
                f"{self.path}: cannot record {row.recording} of {row.unit}: {exc}; the rows before it are kept, "
                "and a rerun of phid fleet does the rest"
            ) from None

    def set_design(self, unit: str, design: str) -> None:
        """The inventory says which design a unit is of now: every row of it says so (a design
        declared after its recordings were identified needs no rerun)."""
        self.db.execute("UPDATE runs SET design=? WHERE unit=? AND design<>?", (design, unit, design))

    def rows(self, unit: str | None = None) -> list[Row]:
        """Rows of one unit (or all), in recording time order (failures without a time last)."""
        where, args = ("WHERE unit=?", (unit,)) if unit is not None else ("", ())
        order = "ORDER BY unit, start_ns IS NULL, start_ns, id"
        cur = self.db.execute(f"SELECT {', '.join(_COLUMNS)} FROM runs {where} {order}", args)
        return [_row(dict(zip(_COLUMNS, r))) for r in cur]

    def units(self) -> list[str]:
        return [u for (u,) in self.db.execute("SELECT DISTINCT unit FROM runs ORDER BY unit")]


def _real(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def _row(r: dict[str, Any]) -> Row:
    row = Row(**{c: r[c] for c in _SCALARS})
    row.wall_s = math.nan if row.wall_s is None else row.wall_s
    for n in PARAMETER_NAMES:
        row.values[n] = math.nan if r[n] is None else r[n]
        row.stds[n] = math.nan if r[f"{n}_std"] is None else r[f"{n}_std"]
        row.identifiable[n] = bool(r[f"{n}_identifiable"])
    row.flags = json.loads(r["flags"] or "[]")
    row.effects = json.loads(r["effects"] or "[]")
    row.controls = json.loads(r["controls"] or "{}")
    row.verdicts = json.loads(r["verdicts"] or "[]")
    return row


@dataclass(frozen=True)
class Change:
    """A parameter moved by more than ``DRIFT_SIGMAS`` between two consecutive well-identified sets."""

    unit: str
    parameter: str
    before: Row
    after: Row
    sigmas: float  # |after − before| / sqrt(σ_before² + σ_after²)

    @property
    def relative(self) -> float:
        return self.after.values[self.parameter] / self.before.values[self.parameter] - 1.0


def changes(rows: Sequence[Row], sigmas: float = DRIFT_SIGMAS) -> list[Change]:
    """Per parameter, compare each well-identified set with the previous well-identified one.

    The σ are the reported total standard deviations (noise and model-bias allowance), so a
    bias both sets share makes the test conservative, never alarming.
    """
    found: list[Change] = []
    for _, unit_rows in iter_units(rows):
        timed = sorted(
            (r for r in unit_rows if r.status == "ok" and r.start_ns is not None), key=lambda r: r.start_ns or 0
        )
        for name in PARAMETER_NAMES:
            good = [r for r in timed if r.well_identified(name)]
            for a, b in zip(good, good[1:]):
                z = abs(b.values[name] - a.values[name]) / math.hypot(a.stds[name], b.stds[name])
                if z > sigmas:
                    found.append(Change(b.unit, name, a, b, z))
    return sorted(found, key=lambda c: (c.unit, c.after.start_ns or 0, c.parameter))


def iter_units(rows: Sequence[Row]) -> Iterator[tuple[str, list[Row]]]:
    units: dict[str, list[Row]] = {}
    for r in rows:
        units.setdefault(r.unit, []).append(r)
    yield from units.items()


SISTER_SIGMAS = 2.0  # sister units' latest values further apart than this many combined σ: said


@dataclass(frozen=True)
class SisterGap:
    """Two units of one design whose latest well-identified values of a parameter differ by more
    than ``SISTER_SIGMAS`` combined standard deviations: one design, one machine, so one of the
    two sets (or a unit) is not what it should be."""

    design: str
    parameter: str
    first: Row
    second: Row
    sigmas: float

    @property
    def relative(self) -> float:
        return self.second.values[self.parameter] / self.first.values[self.parameter] - 1.0

    def text(self) -> str:
        a, b = self.first, self.second
        name = SYMBOLS[self.parameter]
        return (
            f"{name}: sister units {a.unit} {a.values[self.parameter]:.4g} ± {a.stds[self.parameter]:.2g} and "
            f"{b.unit} {b.values[self.parameter]:.4g} ± {b.stds[self.parameter]:.2g} ({self.relative:+.1%}, "
            f"{self.sigmas:.1f} σ apart; design {self.design})"
        )


def row_of_result(unit: str, doc: dict[str, Any], design: str) -> Row:
    """An identification's results document (``phid identify --json``) as a history row of
    ``unit`` and ``design``: what a sister comparison reads (withheld values are null there)."""

    def numbers(key: str) -> dict[str, float]:
        got = doc.get(key) or {}
        return {n: float(got[n]) if isinstance(got.get(n), (int, float)) else math.nan for n in PARAMETER_NAMES}

    flags = doc.get("identifiable") or {}
    return Row(
        unit,
        unit,
        "",
        "ok",
        "",
        start_ns=0,
        values=numbers("parameters"),
        stds=numbers("uncertainty"),
        identifiable={n: flags.get(n) is True for n in PARAMETER_NAMES},
        design=design,
    )


def latest_well_identified(rows: Sequence[Row], name: str) -> Row | None:
    timed = [r for r in rows if r.well_identified(name) and r.start_ns is not None]
    return max(timed, key=lambda r: r.start_ns or 0, default=None)


def sister_gaps(rows: Sequence[Row], sigmas: float = SISTER_SIGMAS) -> list[SisterGap]:
    """For every design with two or more units, each parameter's latest well-identified value of
    each unit against every sister's; the pairs beyond ``sigmas`` combined σ."""
    designs: dict[str, dict[str, list[Row]]] = {}
    for r in rows:
        if r.design:
            designs.setdefault(r.design, {}).setdefault(r.unit, []).append(r)
    found: list[SisterGap] = []
    for design, units in sorted(designs.items()):
        names = sorted(units)
        for name in PARAMETER_NAMES:
            latest = [(u, latest_well_identified(units[u], name)) for u in names]
            for i, (_, a) in enumerate(latest):
                for _, b in latest[i + 1 :]:
                    if a is None or b is None:
                        continue
                    z = abs(b.values[name] - a.values[name]) / math.hypot(a.stds[name], b.stds[name])
                    if z > sigmas:
                        found.append(SisterGap(design, name, a, b, z))
    return found


def designs_of(rows: Sequence[Row]) -> dict[str, list[str]]:
    """Each design and its units (only designs of two or more units: one unit has no sister)."""
    units: dict[str, set[str]] = {}
    for r in rows:
        if r.design:
            units.setdefault(r.design, set()).add(r.unit)
    return {d: sorted(u) for d, u in sorted(units.items()) if len(u) > 1}
