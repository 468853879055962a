"""Persistent event store: every completed event window, on disk as it completes.

SQLite (standard library), for three reasons: each event is written in one
transaction, so after a crash or restart an event is either fully there or not
at all; "the latest N events per kind" is one indexed query; and it is a single
file next to the node, with no server. Arrays are stored as little-endian
float64 / int64 blobs (the stamps as start + period, they are uniform).
"""

from __future__ import annotations

import math
import sqlite3
from pathlib import Path

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.io.topics import CHANNELS
from phid_ros.stream.detector import Event, EventWindow

SCHEMA = """
CREATE TABLE IF NOT EXISTS events (
    event_id TEXT PRIMARY KEY, kind TEXT NOT NULL, name TEXT, role TEXT NOT NULL,
    generator_damping INTEGER NOT NULL, inception_ns INTEGER NOT NULL, clearing_ns INTEGER NOT NULL,
    severity REAL, v_prefault REAL, segment INTEGER, start_ns INTEGER NOT NULL, period_ns INTEGER NOT NULL,
    n INTEGER NOT NULL, usable INTEGER NOT NULL, reason TEXT, channels TEXT NOT NULL, data BLOB NOT NULL);
CREATE INDEX IF NOT EXISTS events_kind_time ON events (kind, inception_ns);
"""


class StoreError(PhidError):
    """The event store file cannot be opened or is not an event store."""


class EventStore:
    def __init__(self, path: str | Path = ":memory:") -> None:
        self.path = str(path)
        try:
            self._db = sqlite3.connect(self.path, check_same_thread=False)
            self._db.executescript(SCHEMA)
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"{self.path}: not a usable event store ({exc})") from exc

    def close(self) -> None:
        self._db.close()

    def add(self, w: EventWindow) -> None:
        e = w.event
        start = int(w.t_ns[0]) if len(w.t_ns) else e.inception_ns
        with self._db:  # one transaction per event
            self._db.execute(
                "INSERT OR REPLACE INTO events VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                (
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
                    ",".join(CHANNELS),
                    np.ascontiguousarray(w.values, dtype="<f8").tobytes(),
                ),
            )

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
            q = "SELECT * FROM events WHERE kind = ?"
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
        with self._db:
            self._db.execute("DELETE FROM events")

    @staticmethod
    def _row(r: tuple) -> EventWindow:
        (eid, kind, name, role, damping, inc, clr, sev, vpf, seg, start, period, n, usable, reason, chans, blob) = r
        channels = chans.split(",")
        values = np.frombuffer(blob, dtype="<f8").reshape(n, len(channels)).copy()
        if tuple(channels) != CHANNELS:
            values = values[:, [channels.index(c) for c in CHANNELS]]

        def real(v: float | None) -> float:
            return math.nan if v is None else float(v)  # SQLite stores NaN as NULL

        ev = Event(eid, kind, int(inc), int(clr), real(sev), real(vpf), int(seg), name or "", role, bool(damping))
        t = int(start) + np.arange(n, dtype=np.int64) * int(period)
        return EventWindow(ev, t, values, int(period), bool(usable), reason or "")
