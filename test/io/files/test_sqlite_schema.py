"""One schema-version scheme for the event store and the fleet history (io/files/sqlite_schema.py)."""

from __future__ import annotations

import sqlite3

import pytest

from phid_ros.errors import PhidError
from phid_ros.fleet.history import SCHEMA_STEPS as HISTORY_STEPS
from phid_ros.fleet.history import History, HistoryError
from phid_ros.io.files.sqlite_schema import migrate, table_columns, user_version
from phid_ros.stream.store import SCHEMA_STEPS as STORE_STEPS
from phid_ros.stream.store import EventStore, StoreError


class _Err(PhidError):
    """An owner's error type, as the store and the history pass theirs."""


def _db(path) -> sqlite3.Connection:
    return sqlite3.connect(path, isolation_level=None)


def test_steps_run_in_order_once_each(tmp_path):
    ran = []
    steps = ["CREATE TABLE a (x)", lambda db: ran.append(1), "ALTER TABLE a ADD COLUMN y; CREATE TABLE b (z)"]
    db = _db(tmp_path / "f.sqlite")
    assert migrate(db, steps, what="f", error=_Err) == 0
    assert user_version(db) == 3 and table_columns(db, "a") == ["x", "y"] and table_columns(db, "b") == ["z"]
    assert migrate(db, steps, what="f", error=_Err) == 3 and ran == [1]  # nothing runs twice


def test_a_failing_step_leaves_the_file_at_the_version_before(tmp_path):
    db = _db(tmp_path / "f.sqlite")
    with pytest.raises(sqlite3.OperationalError):
        migrate(
            db, ["CREATE TABLE a (x)", "CREATE TABLE b (z); ALTER TABLE nowhere ADD COLUMN q"], what="f", error=_Err
        )
    assert user_version(db) == 1 and table_columns(db, "b") == []  # step 2 rolled back whole


def test_a_newer_file_is_refused_naming_it(tmp_path):
    db = _db(tmp_path / "f.sqlite")
    db.execute("PRAGMA user_version = 7")
    with pytest.raises(_Err, match=r"f: written by a newer phid \(schema 7 > 1\)"):
        migrate(db, ["CREATE TABLE a (x)"], what="f", error=_Err)
    path = tmp_path / "store.sqlite"
    _db(path).execute("PRAGMA user_version = 9")
    with pytest.raises(StoreError, match="store.sqlite: event store: written by a newer phid"):
        EventStore(path)
    path = tmp_path / "history.sqlite"
    _db(path).execute("PRAGMA user_version = 9")
    with pytest.raises(HistoryError, match="history.sqlite: fleet history: written by a newer phid"):
        History(path)


def test_an_event_store_from_before_digests_gains_the_column(tmp_path):
    """A version-1 store (meta 'schema_version', no digest column) as phid wrote it before."""
    path = tmp_path / "old.sqlite"
    db = _db(path)
    for stmt in STORE_STEPS[0].split(";"):
        db.execute(stmt)
    db.execute("INSERT INTO meta VALUES ('schema_version', '1')")
    db.execute("INSERT INTO meta VALUES ('unit', 'G1')")
    db.close()
    store = EventStore(path, unit="G1")
    store.close()
    db = _db(path)
    assert user_version(db) == len(STORE_STEPS) == 4 and "digest" in table_columns(db, "events")
    assert "record" in table_columns(db, "verdicts")  # 4: the record on file's verdicts


def test_a_history_from_before_user_version_is_taken_as_version_1_and_upgraded(tmp_path):
    path = tmp_path / "history.sqlite"
    db = _db(path)
    db.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT)")
    db.execute("INSERT INTO meta VALUES ('schema', '1')")
    for stmt in HISTORY_STEPS[0].split(";"):
        db.execute(stmt)
    db.execute(
        "INSERT INTO runs (unit, recording, content_hash, status, phid_version) VALUES ('G1', 'r', 'h', 'ok', 'x')"
    )
    db.close()
    with History(path) as h:
        assert h.units() == ["G1"]
        (row,) = h.rows()
        assert row.method_version == ""  # made by 0.1.0: no method recorded, so never taken as current
        assert row.controls == {}  # made before the fleet identified the exciter and governor
        assert not h.done("G1", "h", "0.2.0+abc") and h.done_before("G1", "h")
        assert (row.record, row.record_hash, row.verdicts, row.design) == ("", "", [], "")  # 4: before records
    assert user_version(_db(path)) == len(HISTORY_STEPS) == 4


def _damage(path) -> None:
    """Overwrite the middle of every page after the first (the header stays readable)."""
    data = bytearray(path.read_bytes())
    page = int.from_bytes(data[16:18], "big") or 65536
    for start in range(page, len(data), page):
        data[start + 8 : start + page // 2] = b"\xa5" * (page // 2 - 8)
    path.write_bytes(bytes(data))


def _checkpoint(path) -> None:
    db = sqlite3.connect(path)
    db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    db.close()


def test_a_damaged_history_is_one_line_with_a_way_out(tmp_path):
    from phid_ros.fleet.history import Row

    path = tmp_path / "history.sqlite"
    with History(path) as h:
        for k in range(200):
            h.add(Row("G1", f"/rec/{k}.mcap", f"h{k}", "ok", "0.2.0", start_ns=k, end_ns=k + 1, error="x" * 200))
    _checkpoint(path)
    _damage(path)
    with pytest.raises(HistoryError) as err:
        History(path)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"{path}: ") and len(msg) < 600
    assert "mv " in msg or "not a usable fleet history" in msg


def test_a_damaged_event_store_is_one_line_with_a_way_out(tmp_path):
    path = tmp_path / "events.sqlite"
    s = EventStore(path, unit="G1")
    with s._write():
        s._db.execute("CREATE TABLE filler (x TEXT)")
        s._db.executemany("INSERT INTO filler VALUES (?)", [("y" * 500,) for _ in range(400)])
    s.close()
    _checkpoint(path)
    _damage(path)
    with pytest.raises(StoreError) as err:
        EventStore(path, unit="G1")
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"{path}: ")
    assert len(msg) < 600  # the first problem and a count, not every damaged page


def test_a_file_another_process_migrated_meanwhile_is_not_migrated_twice(tmp_path, monkeypatch):
    """Two openers read version 0 of a new file; one migrates it; the other, taking the write lock
    after, must see that: before, it ran step 1 again (stamping the file back to version 1 with
    step 2's column in it) and failed on ALTER TABLE, and so did every later open."""
    import phid_ros.io.files.sqlite_schema as schema

    path = tmp_path / "s.sqlite"
    first, second = _db(path), _db(path)
    assert migrate(first, STORE_STEPS, what="s", error=_Err) == 0
    reads = iter([0])  # the second opener's first read, taken before the first opener migrated
    real = schema.user_version
    monkeypatch.setattr(schema, "user_version", lambda db: _stale(reads, real, db))
    assert migrate(second, STORE_STEPS, what="s", error=_Err) == 0
    assert user_version(second) == len(STORE_STEPS) and table_columns(second, "events").count("digest") == 1
    EventStore(path).close()  # and the next opener finds a usable store


def _stale(reads, real, db) -> int:
    """The stale reads first, then the file's own version."""
    value = next(reads, None)
    return real(db) if value is None else value
