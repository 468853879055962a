"""A full disk, a read-only or forbidden place: one line naming the path and what was kept, no
partial file that looks complete, nothing already there lost (issue 37, item 4).

The machine's disk cannot be filled in a test (and root ignores permissions), so the failing
system call is stood in for: the errors are the ones Linux raises (ENOSPC, EROFS, EACCES)."""

from __future__ import annotations

import errno
import os
import sqlite3

import pytest

from phid_ros.cli.main import main
from phid_ros.io.files import outputs
from phid_ros.io.files.outputs import OutputError, atomic_output, write_text

BAGS = __import__("pathlib").Path(__file__).resolve().parents[3] / "bags"


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS, errno.EACCES])
def test_a_write_that_fails_leaves_the_earlier_file_and_no_partial(tmp_path, monkeypatch, code):
    out = tmp_path / "result.json"
    out.write_text("the earlier result")

    def fail(src, dst):
        raise OSError(code, os.strerror(code), str(dst))

    monkeypatch.setattr(outputs.os, "replace", fail)
    with pytest.raises(OutputError) as err:
        write_text(out, "new")
    msg = str(err.value)
    assert msg == f"{out}: {os.strerror(code)}; nothing written, the earlier result.json is unchanged"
    assert out.read_text() == "the earlier result" and not outputs.partial_path(out).exists()


def test_a_replay_output_cut_by_a_full_disk_keeps_what_was_written(tmp_path):
    out = tmp_path / "replay.mcap"
    with pytest.raises(
        OutputError, match=r"No space left on device; what was written before it is kept in .*replay\.partial\.mcap"
    ):
        with atomic_output(out, keep_partial=True) as tmp:
            tmp.write_bytes(b"the first messages")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # a writer's error names no file
    assert (tmp_path / "replay.partial.mcap").read_bytes() == b"the first messages" and not out.exists()


def test_an_input_s_error_is_not_blamed_on_the_output(tmp_path):
    with pytest.raises(PermissionError):
        with atomic_output(tmp_path / "out.json"):
            raise PermissionError(errno.EACCES, "Permission denied", "/elsewhere/input.csv")


def test_phid_identify_onto_a_full_disk_is_one_line(tmp_path, monkeypatch, capsys):
    def full(self, data, *a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))

    monkeypatch.setattr(outputs.Path, "write_text", full)
    out = tmp_path / "r.json"
    code = main(["identify", str(BAGS / "catalogue"), "--no-baseline", "--json", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1].startswith("phid: error: ") and "No space left on device" in err[-1]
    assert "Traceback" not in "\n".join(err) and not out.exists()
    assert not list(tmp_path.glob("*.partial*"))


def test_a_store_on_a_full_disk_is_one_line_and_keeps_what_it_had(tmp_path, monkeypatch, capsys):
    """The last resort: an OSError of that kind met anywhere is one line, not a traceback."""
    import phid_ros.api

    def readonly(*a, **k):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(tmp_path / "set"))

    monkeypatch.setattr(phid_ros.api, "write_output", readonly)
    code = main(["simulate", "--scenario", "S04", "--duration", "3", "--out", str(tmp_path / "set.mcap")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1] == f"phid: error: {tmp_path / 'set'}: Read-only file system"


def test_a_history_row_that_cannot_be_written_is_one_line(tmp_path):
    from phid_ros.fleet.history import History, HistoryError, Row

    h = History(tmp_path / "history.sqlite")
    h.add(Row("G1", "/rec/a.mcap", "ha", "ok", "0.2.0"))
    h.db.execute("PRAGMA query_only = ON")  # as a read-only file refuses writes
    with pytest.raises(HistoryError, match=r"cannot record /rec/b\.mcap of G1: .*the rows before it are kept"):
        h.add(Row("G1", "/rec/b.mcap", "hb", "ok", "0.2.0"))
    assert [r.recording for r in h.rows()] == ["/rec/a.mcap"]
    h.close()
    assert sqlite3.connect(tmp_path / "history.sqlite").execute("SELECT COUNT(*) FROM runs").fetchone()[0] == 1
