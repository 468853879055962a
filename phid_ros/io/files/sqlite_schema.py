"""One way to version an SQLite file: ``PRAGMA user_version`` and an ordered list of steps.

The event store (``stream/store.py``) and the fleet history (``fleet/history.py``) both keep
SQLite files that outlive a phid release. Each declares its schema as a list of steps, the
n-th of which brings a file from version n to n + 1; :func:`migrate` runs the steps a file
lacks, each in its own transaction with the version it reaches, so a file is never left
between two versions. A file from a newer phid is refused, not written to.

Files written before this scheme kept their version in a ``meta`` table; each owner passes a
``legacy`` function that reads what such a file is, so they migrate like any other.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Callable, Sequence

from phid_ros.errors import PhidError

Step = str | Callable[[sqlite3.Connection], None]  # SQL statements separated by ';', or a function


def user_version(db: sqlite3.Connection) -> int:
    return int(db.execute("PRAGMA user_version").fetchone()[0])


def migrate(
    db: sqlite3.Connection,
    steps: Sequence[Step],
    *,
    what: str,
    error: type[PhidError],
    legacy: Callable[[sqlite3.Connection], int] | None = None,
) -> int:
    """Bring ``db`` to version ``len(steps)``; returns the version it was found at.

    ``what`` names the file in errors (its path and kind); ``error`` is the owner's error type.
    ``legacy`` tells the version of a file whose ``user_version`` is still 0 (0 for a new one).
    """
    found = user_version(db)
    if found == 0 and legacy is not None:
        found = legacy(db)
        latest = len(steps)
        if 0 < found <= latest:  # stamp it, so the legacy reading is done once
            db.execute(f"PRAGMA user_version = {found}")
    latest = len(steps)
    if found > latest:
        raise error(f"{what}: written by a newer phid (schema {found} > {latest}); upgrade phid_ros to read it")
    for version in range(found, latest):
        step = steps[version]
        db.execute("BEGIN IMMEDIATE")
        # another process may have taken the file past this step since its version was read (a
        # poller opening the store while a replay creates it): read again under the write lock.
        # A stale read ran step 1 again and stamped the file back to version 1 while it had step
        # 2's column, and every later open failed ("duplicate column name: digest", the ROS tier's
        # kill -9 test): a store no node could open, its events out of reach
        if user_version(db) > version:
            db.execute("COMMIT")
            continue
        try:
            if callable(step):
                step(db)
            else:
                for stmt in step.split(";"):
                    if stmt.strip():
                        db.execute(stmt)
            db.execute(f"PRAGMA user_version = {version + 1}")  # a pragma takes no bound parameter
        except BaseException:
            db.execute("ROLLBACK")
            raise
        db.execute("COMMIT")
    return found


def table_columns(db: sqlite3.Connection, table: str) -> list[str]:
    """The column names of ``table`` (empty when it does not exist)."""
    return [r[1] for r in db.execute(f"PRAGMA table_info({table})")]


def check_intact(db: sqlite3.Connection, what: str, error: type[PhidError], way_out: str) -> None:
    """SQLite's quick check on open: a damaged file is one line (the first problem and how many
    more), with ``way_out`` (what to do with it), never a dump of every damaged page."""
    found = [str(r[0]) for r in db.execute("PRAGMA quick_check(20)")]
    if found != ["ok"]:
        more = f" and {len(found) - 1}{'+' if len(found) >= 20 else ''} more problems" if len(found) > 1 else ""
        first = " ".join(found[0].split())
        first = first if len(first) <= 120 else first[:117] + "..."
        raise error(f"{what} is damaged (SQLite: {first}{more}); {way_out}")
