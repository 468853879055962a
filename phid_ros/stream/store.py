"""Persistent event store: every completed event window, on disk as it completes.

SQLite (standard library), for three reasons: each event is written in one
transaction, so after a crash or restart an event is either fully there or not
at all; "the latest N events per kind" is one indexed query; and it is a single
file next to the node, with no server. Arrays are stored as little-endian
float64 / int64 blobs (the stamps as start + period, they are uniform).

A store belongs to one generating unit: the first writer names it, and events of
another unit are refused, so a recalibration never mixes two machines. An event's
id is its kind and inception stamp (:func:`~phid_ros.stream.detector.event_id`),
with a digest of its samples beside it: the same event written again (a restart,
the same recording replayed) is recognised and kept once; a complete window
replaces an incomplete one of the same event; a *different* window under the same
id means two recordings are being mixed under one unit name, and is refused.
Writers are serialised by SQLite's write lock (``BEGIN IMMEDIATE``, WAL journal),
so two processes on one store each add their events and lose none.
"""

from __future__ import annotations

import hashlib
import json
import math
import sqlite3
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.io.files.results import json_ready
from phid_ros.io.files.sqlite_schema import check_intact, migrate, table_columns
from phid_ros.model.channels import CHANNELS
from phid_ros.stream.detector import Event, EventWindow

# the store's schema, step by step (io/files/sqlite_schema.py): version n + 1 is steps[:n + 1] applied
SCHEMA_STEPS = (
    """
    CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
    CREATE TABLE IF NOT EXISTS events (
        event_id TEXT PRIMARY KEY, kind TEXT NOT NULL, name TEXT, role TEXT NOT NULL,
        generator_damping INTEGER NOT NULL, inception_ns INTEGER NOT NULL, clearing_ns INTEGER NOT NULL,
        severity REAL, v_prefault REAL, segment INTEGER, start_ns INTEGER NOT NULL, period_ns INTEGER NOT NULL,
        n INTEGER NOT NULL, usable INTEGER NOT NULL, reason TEXT, channels TEXT NOT NULL, data BLOB NOT NULL);
    CREATE INDEX IF NOT EXISTS events_kind_time ON events (kind, inception_ns)
    """,
    # 2: a digest of the samples, so that a replayed event is told from a different one
    "ALTER TABLE events ADD COLUMN digest TEXT NOT NULL DEFAULT ''",
    # 3: what the test sheet says of the event's scenario (its marker's), which the identification reads
    """
    ALTER TABLE events ADD COLUMN regulator TEXT NOT NULL DEFAULT '';
    ALTER TABLE events ADD COLUMN reference_step REAL
    """,
    # 4: the verdict of the unit's record on file for each event (stream/record_check.py), by record
    """
    CREATE TABLE IF NOT EXISTS verdicts (
        event_id TEXT NOT NULL, record TEXT NOT NULL, passed INTEGER NOT NULL, verdict TEXT NOT NULL,
        PRIMARY KEY (event_id, record))
    """,
)
COLUMNS = (
    "event_id, kind, name, role, generator_damping, inception_ns, clearing_ns, severity, v_prefault, segment, "
    "start_ns, period_ns, n, usable, reason, channels, data, regulator, reference_step"
)
BUSY_TIMEOUT_S = 30.0  # how long a writer waits for another process's transaction before giving up


class StoreError(PhidError):
    """The event store file cannot be opened, is damaged, belongs to another unit, or refuses an event."""


def window_digest(w: EventWindow) -> str:
    """A digest of what was measured: stamps and samples (not labels, which markers may add later)."""
    h = hashlib.sha256()
    start = int(w.t_ns[0]) if len(w.t_ns) else w.event.inception_ns
    h.update(np.array([start, w.period_ns, len(w.t_ns)], dtype="<i8").tobytes())
    h.update(np.ascontiguousarray(w.values, dtype="<f8").tobytes())
    for c, x in w.recorded.items():  # a window without them keeps the digest it always had
        h.update(c.encode())
        h.update(np.ascontiguousarray(x, dtype="<f8").tobytes())
    return h.hexdigest()


def _same_samples(a: EventWindow, b: EventWindow) -> bool:
    """Do two windows of one event agree wherever both have samples (the same measurement)?"""
    common, ia, ib = np.intersect1d(a.t_ns, b.t_ns, assume_unique=True, return_indices=True)
    if common.size == 0:
        return a.period_ns == b.period_ns
    return bool(np.array_equal(a.values[ia], b.values[ib], equal_nan=True))


def _more_complete(new: EventWindow, stored: EventWindow) -> bool:
    """Does ``new`` (the same event, its samples agreeing with ``stored``'s) say more? A usable
    window over an unusable one, a longer one of two unusable ones, and one that carries a
    recorder's channel the stored one lacks (a store written by an earlier version, whose windows
    held no field current, was kept over the recording's own: X'_d published at 0.454 for 0.5)."""
    if stored.usable and not new.usable:
        return False
    gains = set(new.recorded) - set(stored.recorded)
    loses = set(stored.recorded) - set(new.recorded)
    if gains and not loses and len(new.t_ns) >= len(stored.t_ns):
        return True
    if loses:
        return False
    return not stored.usable and (new.usable or len(new.t_ns) > len(stored.t_ns))


def _legacy_version(db: sqlite3.Connection) -> int:
    """A store from before ``user_version``: 2 with the digest column, else 0.

    A store without digests may also lack the meta table; step 1 only creates what is missing,
    so such a store is taken through it again rather than called version 1.
    """
    return 2 if "digest" in table_columns(db, "events") else 0


class EventStore:
    def __init__(
        self, path: str | Path = ":memory:", *, unit: str | None = None, retain_per_kind: int | None = None
    ) -> None:
        """``retain_per_kind``: keep of each kind only the newest this many usable (and unusable)
        windows, the most a recalibration reads: a store in memory then holds as much for a day of
        replay as for an hour (a file store keeps every event, on disk)."""
        self.path = str(path)
        self.retain_per_kind = retain_per_kind
        try:
            self._db = sqlite3.connect(self.path, check_same_thread=False, timeout=BUSY_TIMEOUT_S, isolation_level=None)
            if self.path != ":memory:":
                self._db.execute("PRAGMA journal_mode=WAL")
            check_intact(
                self._db,
                f"{self.path}: event store",
                StoreError,
                f"move it away (mv {self.path} {self.path}.damaged) and start again: the events in it are "
                "detected again from a replay of the recording",
            )
            self._migrate()
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"{self.path}: not a usable event store ({exc})") from exc
        self.unit = self._claim(unit)

    # -- identity ----------------------------------------------------------------------
    def _migrate(self) -> None:
        migrate(self._db, SCHEMA_STEPS, what=f"{self.path}: event store", error=StoreError, legacy=_legacy_version)

    def _claim(self, unit: str | None) -> str | None:
        with self._write():
            row = self._db.execute("SELECT value FROM meta WHERE key = 'unit'").fetchone()
            if row is None:
                if unit:
                    self._db.execute("INSERT INTO meta VALUES ('unit', ?)", (unit,))
                return unit or None
        if unit and row[0] != unit:
            raise StoreError(
                f"{self.path}: this event store belongs to unit {row[0]!r}, not {unit!r}; "
                "use another store for another machine"
            )
        return str(row[0])

    # -- writing -------------------------------------------------------------------------
    class _Tx:
        def __init__(self, db: sqlite3.Connection) -> None:
            self.db = db

        def __enter__(self) -> None:
            self.db.execute("BEGIN IMMEDIATE")  # take the write lock now: writers queue, none overwrites

        def __exit__(self, kind: object, exc: object, tb: object) -> None:
            self.db.execute("COMMIT" if kind is None else "ROLLBACK")

    def _write(self) -> EventStore._Tx:
        return EventStore._Tx(self._db)

    def close(self) -> None:
        self._db.close()

    def add(self, w: EventWindow) -> str:
        """Store a window; returns 'added', 'duplicate' (already there), 'relabelled' (already there,
        the test sheet's labels now given), 'replaced' (a more complete window for a stored one:
        complete for incomplete, with a recorder's channel it lacked) or 'kept' (a less complete one)."""
        e = w.event
        digest = window_digest(w)
        try:
            with self._write():
                row = self._db.execute(
                    f"SELECT digest, {COLUMNS} FROM events WHERE event_id = ?", (e.event_id,)
                ).fetchone()
                if row is not None:
                    stored = self._row(row[1:])
                    if row[0] == digest:
                        return self._relabel(stored, w)
                    if not _same_samples(stored, w):
                        raise StoreError(
                            f"{self.path}: event {e.event_id} is already stored with other samples; two "
                            f"recordings are being mixed under unit {self.unit!r} (use another store or unit)"
                        )
                    if not _more_complete(w, stored):
                        return "kept"  # the stored window is the more complete one of the same event
                self._db.execute(
                    f"INSERT OR REPLACE INTO events ({COLUMNS}, digest) VALUES ({'?,' * 19}?)",
                    (
                        *self._values(w),
                        digest,
                    ),
                )
                if self.retain_per_kind is not None:
                    self._db.execute(
                        "DELETE FROM events WHERE kind = ? AND usable = ? AND event_id NOT IN (SELECT event_id "
                        "FROM events WHERE kind = ? AND usable = ? ORDER BY inception_ns DESC LIMIT ?)",
                        (e.kind, int(w.usable), e.kind, int(w.usable), self.retain_per_kind),
                    )
                return "added" if row is None else "replaced"
        except sqlite3.OperationalError as exc:  # the lock was not released within the busy timeout
            raise StoreError(f"{self.path}: cannot write event {e.event_id}: {exc}") from exc

    def _relabel(self, stored: EventWindow, w: EventWindow) -> str:
        """The same samples again: 'duplicate', but a test sheet's labels the new window carries
        (the regulator, a reference step, given in a map after the first replay) are taken; a store's
        old labels were otherwise kept over the sheet's, silently."""
        new, old = w.event, stored.event
        labels = (new.regulator, new.reference_step)
        if labels == (old.regulator, old.reference_step) or labels == ("", None):
            return "duplicate"
        self._db.execute(
            "UPDATE events SET regulator = ?, reference_step = ? WHERE event_id = ?", (*labels, new.event_id)
        )
        return "relabelled"

    @staticmethod
    def _values(w: EventWindow) -> tuple:
        e = w.event
        start = int(w.t_ns[0]) if len(w.t_ns) else e.inception_ns
        return (
            e.event_id,
            e.kind,
            e.name,
            e.role,
            int(e.generator_damping),
            e.inception_ns,
            e.clearing_ns,
            e.severity,
            e.v_prefault,
            e.segment,
            start,
            w.period_ns,
            len(w.t_ns),
            int(w.usable),
            w.reason,
            ",".join((*CHANNELS, *w.recorded)),
            np.ascontiguousarray(np.column_stack([w.values, *w.recorded.values()]), dtype="<f8").tobytes(),
            e.regulator,
            e.reference_step,
        )

    def add_verdict(self, event_id: str, record: str, passed: bool, verdict: Mapping[str, Any]) -> None:
        """The record's verdict on a stored event (its JSON), beside the window; the same event
        checked again against the same record replaces its verdict."""
        with self._write():
            self._db.execute(
                "INSERT OR REPLACE INTO verdicts VALUES (?, ?, ?, ?)",
                (event_id, record, int(passed), json.dumps(json_ready(verdict))),
            )

    def verdicts(self, record: str | None = None) -> list[dict[str, Any]]:
        """The verdicts kept, by event time, each with its record (all records, or one)."""
        q = "SELECT v.record, v.verdict FROM verdicts v LEFT JOIN events e ON e.event_id = v.event_id"
        args: tuple = ()
        if record is not None:
            q += " WHERE v.record = ?"
            args = (record,)
        q += " ORDER BY e.inception_ns, v.event_id"
        return [{"record": r, **json.loads(doc)} for r, doc in self._db.execute(q, args)]

    # -- reading -------------------------------------------------------------------------
    def __len__(self) -> int:
        return int(self._db.execute("SELECT COUNT(*) FROM events").fetchone()[0])

    def counts(self, usable_only: bool = True) -> dict[str, int]:
        q = "SELECT kind, COUNT(*) FROM events" + (" WHERE usable = 1" if usable_only else "") + " GROUP BY kind"
        return {k: int(n) for k, n in self._db.execute(q)}

    def latest(
        self, kind: str | None = None, n: int | None = None, *, role: str | None = None, usable_only: bool = True
    ) -> list[EventWindow]:
        """Newest first within each kind; ``n`` per kind when ``kind`` is None."""
        kinds = [kind] if kind else [r[0] for r in self._db.execute("SELECT DISTINCT kind FROM events")]
        out: list[EventWindow] = []
        for k in kinds:
            q = f"SELECT {COLUMNS} FROM events WHERE kind = ?"
            args: list[object] = [k]
            if usable_only:
                q += " AND usable = 1"
            if role:
                q += " AND role = ?"
                args.append(role)
            q += " ORDER BY inception_ns DESC"
            if n is not None:
                q += f" LIMIT {int(n)}"
            out.extend(self._row(r) for r in self._db.execute(q, args))
        out.sort(key=lambda w: w.event.inception_ns)
        return out

    def all(self) -> list[EventWindow]:
        return self.latest(usable_only=False)

    def clear(self) -> None:
        with self._write():
            self._db.execute("DELETE FROM events")
            self._db.execute("DELETE FROM verdicts")

    def integrity(self) -> str:
        """SQLite's full integrity check plus ours: every stored blob has the size its row says."""
        ok = self._db.execute("PRAGMA integrity_check").fetchone()[0]
        if ok != "ok":
            return ok
        bad = self._db.execute(
            "SELECT event_id FROM events WHERE length(data) != n * 8 * (length(channels) - "
            "length(replace(channels, ',', '')) + 1)"
        ).fetchall()
        return "ok" if not bad else f"events with a wrong data size: {[r[0] for r in bad]}"

    @staticmethod
    def _row(r: tuple) -> EventWindow:
        eid, kind, name, role, damping, inc, clr, sev, vpf, seg, start, period, n, usable, reason, chans, blob = r[:17]
        regulator, reference_step = r[17:]
        channels = chans.split(",")
        stored = np.frombuffer(blob, dtype="<f8").reshape(n, len(channels))
        values = stored[:, [channels.index(c) for c in CHANNELS]].copy()
        # a recorder's own channels stored beside them (a store from before keeps none)
        recorded = {c: stored[:, j].copy() for j, c in enumerate(channels) if c not in CHANNELS}

        def real(v: float | None) -> float:
            return math.nan if v is None else float(v)  # SQLite stores NaN as NULL

        ev = Event(eid, kind, int(inc), int(clr), real(sev), real(vpf), int(seg), name or "", role, bool(damping))
        ev.regulator, ev.reference_step = regulator or "", None if reference_step is None else float(reference_step)
        t = int(start) + np.arange(n, dtype=np.int64) * int(period)
        return EventWindow(
            t_ns=t,
            values=values,
            period_ns=int(period),
            event=ev,
            usable=bool(usable),
            reason=reason or "",
            recorded=recorded,
        )
