"""The event store across runs: unique ids, restarts, two recordings, two units, two writers, kill -9."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import replace

import numpy as np
import pytest

from phid_ros.model.channels import CHANNELS
from phid_ros.model.conventions import NS
from phid_ros.stream.detector import Event, EventWindow, event_id
from phid_ros.stream.store import EventStore, StoreError

T0 = 1_767_225_600 * NS


def window(k: int, *, offset: float = 0.0, usable: bool = True, n: int = 200) -> EventWindow:
    inc = T0 + k * 60 * NS
    ev = Event(event_id("fault", inc), "fault", inc, inc + NS // 10, 0.8, 1.0, 0)
    t = inc - NS + np.arange(n, dtype=np.int64) * 1_000_000
    x = np.full((n, len(CHANNELS)), 0.9 + offset) + 1e-3 * k
    return EventWindow(
        t_ns=t, values=x, period_ns=1_000_000, event=ev, usable=usable, reason="" if usable else "the data ended early"
    )


def test_ids_come_from_the_event_not_a_counter():
    a, b = window(1), window(2)
    assert a.event.event_id == "fault@2026-01-01T00:01:00.000000000Z" and a.event.event_id != b.event.event_id


def test_the_same_event_again_is_recognised_not_duplicated(tmp_path):
    path = tmp_path / "s.sqlite"
    s = EventStore(path, unit="G1")
    assert [s.add(window(k)) for k in range(3)] == ["added"] * 3
    s.close()
    s = EventStore(path, unit="G1")  # a restart, the same recording again
    assert [s.add(window(k)) for k in range(4)] == ["duplicate"] * 3 + ["added"]
    assert len(s) == 4 and s.integrity() == "ok"


def test_a_complete_window_replaces_an_incomplete_one_and_not_the_reverse(tmp_path):
    s = EventStore(tmp_path / "s.sqlite")
    assert s.add(window(1, usable=False, n=100)) == "added"
    assert s.add(window(1)) == "replaced"
    assert s.add(window(1, usable=False, n=100)) == "kept"
    [w] = s.all()
    assert w.usable and len(w.t_ns) == 200


def test_a_second_recording_under_the_same_unit_cannot_overwrite(tmp_path):
    s = EventStore(tmp_path / "s.sqlite", unit="G1")
    s.add(window(1))
    with pytest.raises(StoreError, match="already stored with other samples.*two recordings"):
        s.add(window(1, offset=0.1))  # same stamp, other samples: another machine's data
    [w] = s.all()
    assert np.all(w.values[:, 0] == 0.9 + 1e-3)  # the first recording's event is untouched


def test_a_store_refuses_another_unit(tmp_path):
    path = tmp_path / "s.sqlite"
    EventStore(path, unit="G1").close()
    with pytest.raises(StoreError, match="belongs to unit 'G1', not 'G2'"):
        EventStore(path, unit="G2")
    assert EventStore(path).unit == "G1"  # opened without a unit: it keeps its own


WRITER = """
import sys, numpy as np
sys.path.insert(0, {test_dir!r})
from test_store import window
from phid_ros.stream.store import EventStore
s = EventStore(sys.argv[1], unit="G1")
first = int(sys.argv[2])
for k in range(first, first + 40):
    assert s.add(window(k)) == "added"
s.close()
"""


def test_two_concurrent_writers_lose_nothing(tmp_path):
    path = tmp_path / "s.sqlite"
    EventStore(path, unit="G1").close()
    code = WRITER.format(test_dir=os.path.dirname(__file__))
    procs = [subprocess.Popen([sys.executable, "-c", code, str(path), str(first)]) for first in (0, 1000)]
    assert [p.wait(timeout=120) for p in procs] == [0, 0]
    s = EventStore(path)
    assert len(s) == 80 and s.integrity() == "ok"
    ids = [w.event.event_id for w in s.all()]
    assert len(set(ids)) == 80


def test_kill_9_during_a_recalibration_then_restart(tmp_path, short_recording):
    """The process dies mid-run; the store is intact and a rerun completes it without duplicates."""
    from phid_ros.io.bags.recordings import write_recording

    bag = write_recording(tmp_path / "rec.mcap", short_recording)
    store = tmp_path / "s.sqlite"
    run = [sys.executable, "-m", "phid_ros.cli.main", "replay", str(bag), "--store", str(store), "--unit", "G1"]
    p = subprocess.Popen([*run, "--out", str(tmp_path / "a.mcap"), "--rate", "4"])
    deadline = time.time() + 120
    while time.time() < deadline:
        time.sleep(0.2)
        if store.exists():
            try:
                s = EventStore(store)
                n = len(s)
                s.close()
            except StoreError:
                n = 0
            if n >= 2:
                break
    p.send_signal(signal.SIGKILL)
    p.wait()
    s = EventStore(store)
    assert s.integrity() == "ok"
    before = {w.event.event_id for w in s.all()}
    s.close()
    assert len(before) >= 2
    assert subprocess.run([*run, "--out", str(tmp_path / "b.mcap")], capture_output=True).returncode == 0
    s = EventStore(store)
    after = [w.event.event_id for w in s.all()]
    assert s.integrity() == "ok" and before <= set(after) and len(after) == len(set(after))
    # the same as one clean run into an empty store
    clean = tmp_path / "clean.sqlite"
    assert subprocess.run([*run[:5], "--store", str(clean), "--out", str(tmp_path / "c.mcap")]).returncode == 0
    c = EventStore(clean)
    assert sorted(after) == sorted(w.event.event_id for w in c.all())


def test_replaying_two_machines_into_one_store_is_refused(tmp_path, short_recording, capsys):
    """The bug report: a second recording's events replaced the first's. Now: a clear refusal."""
    from phid_ros.cli.main import main
    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.io.recording import Recording, StreamSamples

    a = write_recording(tmp_path / "a.mcap", short_recording)
    other = Recording(
        {
            k: StreamSamples(s.t_ns, s.period_ns, {c: v * (1.02 if c == "i_d" else 1.0) for c, v in s.channels.items()})
            for k, s in short_recording.streams.items()
        },
        list(short_recording.scenarios),
        dict(short_recording.metadata),
    )
    b = write_recording(tmp_path / "b.mcap", other)
    store = tmp_path / "s.sqlite"
    assert main(["replay", str(a), "--store", str(store), "--unit", "G1", "--out", str(tmp_path / "o1.mcap")]) == 0
    n = len(EventStore(store))
    capsys.readouterr()
    assert main(["replay", str(b), "--store", str(store), "--unit", "G1", "--out", str(tmp_path / "o2.mcap")]) == 2
    assert "already stored with other samples" in capsys.readouterr().err
    assert main(["replay", str(b), "--store", str(store), "--unit", "G2", "--out", str(tmp_path / "o3.mcap")]) == 2
    assert "belongs to unit 'G1', not 'G2'" in capsys.readouterr().err
    s = EventStore(store)
    assert len(s) == n and s.integrity() == "ok"


def test_a_store_from_before_digests_opens(tmp_path):
    import sqlite3

    path = tmp_path / "old.sqlite"
    db = sqlite3.connect(path)
    db.executescript(
        """CREATE TABLE events (
    event_id TEXT PRIMARY KEY, kind TEXT NOT NULL, name TEXT, role TEXT NOT NULL,
    generator_damping INTEGER NOT NULL, inception_ns INTEGER NOT NULL, clearing_ns INTEGER NOT NULL,
    severity REAL, v_prefault REAL, segment INTEGER, start_ns INTEGER NOT NULL, period_ns INTEGER NOT NULL,
    n INTEGER NOT NULL, usable INTEGER NOT NULL, reason TEXT, channels TEXT NOT NULL, data BLOB NOT NULL);"""
    )
    db.close()
    s = EventStore(path, unit="G1")
    assert s.add(replace(window(1))) == "added" and len(s) == 1


def test_a_window_keeps_the_recorder_s_channels_and_its_test_sheet_through_the_store(tmp_path):
    """The field current (and the regulator's output) stored beside the ten channels, the marker's
    regulator and reference step beside the event, all back as written; a version-2 store (a
    node's, from before) takes the new columns and keeps its events."""
    import sqlite3

    path = tmp_path / "s.sqlite"
    old = EventStore(path, unit="G1")
    old.add(window(1))
    old.close()
    db = sqlite3.connect(path)  # as the previous schema left it
    db.executescript("ALTER TABLE events DROP COLUMN regulator; ALTER TABLE events DROP COLUMN reference_step;")
    db.execute("PRAGMA user_version = 2")
    db.close()
    w = window(2)
    w.recorded = {"i_fd": np.linspace(0.5, 0.6, len(w.t_ns)), "v_r": np.full(len(w.t_ns), 2.5)}
    w.event.regulator, w.event.reference_step = "manual", 0.05
    s = EventStore(path, unit="G1")
    assert s.add(w) == "added" and s.integrity() == "ok"
    first, second = s.latest()
    assert first.recorded == {} and first.event.regulator == "" and first.event.reference_step is None
    assert np.array_equal(second.values, w.values) and set(second.recorded) == {"i_fd", "v_r"}
    assert all(np.array_equal(second.recorded[c], w.recorded[c]) for c in w.recorded)
    assert (second.event.regulator, second.event.reference_step) == ("manual", 0.05)
    assert s.add(second) == "duplicate"  # its digest covers the recorder's channels too


def test_a_window_written_by_an_earlier_version_gives_way_to_the_recordings_own(tmp_path):
    """A store written before windows kept the field current, replayed with the same trend logs:
    its old windows were kept over the recording's own, and X'_d was published at 0.454 ± 0.013
    (true 0.5) where a fresh store withholds it. The window carrying the recorder's channels now
    replaces the one without; the sheet's labels given later replace none; nothing is dropped
    the other way round."""
    path = tmp_path / "s.sqlite"
    s = EventStore(path, unit="G1")
    assert s.add(window(1)) == "added"  # as the earlier version stored it: the ten channels alone
    new = window(1)
    new.recorded = {"i_fd": np.linspace(0.5, 0.6, len(new.t_ns))}
    assert s.add(new) == "replaced"
    [got] = s.latest()
    assert set(got.recorded) == {"i_fd"} and np.array_equal(got.recorded["i_fd"], new.recorded["i_fd"])
    assert s.add(window(1)) == "kept"  # the window without it never replaces the one with it
    # the same samples with the test sheet's labels, given in a map after the first replay
    new.event.regulator, new.event.reference_step = "manual", 0.1
    assert s.add(new) == "relabelled"
    [got] = s.latest()
    assert (got.event.regulator, got.event.reference_step) == ("manual", 0.1) and len(s) == 1
    plain = window(1)
    plain.recorded = dict(new.recorded)
    assert s.add(plain) == "duplicate"  # a window without labels leaves the sheet's in place
    assert s.latest()[0].event.regulator == "manual"
