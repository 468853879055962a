"""``phid fleet``: every recording of an inventory as one task on a Dask cluster, into the history.

The driver alone touches the history: it skips what is already there (same unit, content and
phid version, so an interrupted run resumes), submits the rest, and stores each row the moment
its task ends. One driver per fleet folder at a time (an exclusive lock), so two runs cannot
interleave their rows or do the same work twice.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from phid_ros import __version__
from phid_ros.errors import PhidError
from phid_ros.extras import require
from phid_ros.fleet.history import History, Row
from phid_ros.fleet.inventory import Item, discover
from phid_ros.fleet.task import one_line, process_recording
from phid_ros.io.files.digest import content_hash, stat_key
from phid_ros.provenance import method_version

if TYPE_CHECKING:
    from distributed import Client

HISTORY_FILE = "history.sqlite"
LOCK_FILE = ".phid-fleet.lock"


@dataclass(frozen=True)
class FleetOptions:
    scheduler: str | None = None  # an existing cluster; None: a local one
    workers: int = 0  # local cluster processes, 0: one per core
    diagnose: bool = False
    retry_failed: bool = False  # run again what failed with this version (a worker lost, a file fixed in place)
    dashboard: bool = True


@dataclass
class FleetRun:
    recordings: int = 0
    skipped: int = 0
    redone: int = 0  # in the history from an older method version, identified again
    submitted: int = 0
    rows: list[Row] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def failed(self) -> int:
        return sum(r.status == "failed" for r in self.rows)


@contextmanager
def fleet_lock(fleet_dir: Path) -> Iterator[None]:
    """The fleet folder for this process alone, or a one-line refusal naming the holder."""
    path = fleet_dir / LOCK_FILE
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "?"
            raise PhidError(
                f"{fleet_dir}: another phid fleet run (pid {holder}) is using this folder; "
                "wait for it or give another --out"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    finally:
        os.close(fd)  # releases the lock, also when the process is killed


def run_fleet(
    inventory: str | Path,
    fleet_dir: str | Path,
    options: FleetOptions = FleetOptions(),
    *,
    on_cluster: Callable[[Client], None] | None = None,
    on_row: Callable[[Row, int, int], None] | None = None,
    on_hashing: Callable[[int, int], None] | None = None,
) -> FleetRun:
    """Run the inventory's new recordings; ``on_row(row, done, total)`` after each stored row."""
    items, warnings = discover(inventory)
    out = Path(fleet_dir)
    if not out.parent.is_dir():
        raise PhidError(f"--out {out}: its parent folder {out.parent} does not exist")
    out.mkdir(exist_ok=True)
    result = FleetRun(recordings=len(items), warnings=warnings)
    method = method_version()
    with fleet_lock(out), History(out / HISTORY_FILE) as history:
        for unit, design in {i.unit: i.design for i in items}.items():
            history.set_design(unit, design)
        todo: list[tuple[Item, str]] = []
        for k, item in enumerate(items):
            if on_hashing:
                on_hashing(k, len(items))
            if not item.path.exists():
                h = f"missing:{item.path}"
                if not history.done(item.unit, h, method):
                    row = Row(item.unit, str(item.path), h, "failed", __version__, error=f"{item.path}: no such file")
                    row.method_version, row.design = method, item.design
                    _store(history, result, row, on_row, len(items))
                continue
            h = _hash(history, item.path)
            if history.done(item.unit, h, method, _record_hash(history, item)) and not (
                options.retry_failed and history.failed(item.unit, h, method)
            ):
                result.skipped += 1
                continue
            if history.done_before(item.unit, h):
                result.redone += 1  # identified by an older method: its numbers may have moved
            todo.append((item, h))
        if todo:
            _run_tasks(todo, history, result, options, on_cluster, on_row)
    return result


def _record_hash(history: History, item: Item) -> str:
    return _hash(history, item.record) if item.record is not None else ""


def _hash(history: History, path: Path) -> str:
    key = stat_key(path)
    cached = history.cached_hash(path, key)
    if cached is None:
        cached = content_hash(path)
        history.cache_hash(path, key, cached)
    return cached


def _run_tasks(
    todo: list[tuple[Item, str]],
    history: History,
    result: FleetRun,
    options: FleetOptions,
    on_cluster: Callable[[Client], None] | None,
    on_row: Callable[[Row, int, int], None] | None,
) -> None:
    from phid_ros.cluster import cluster

    as_completed = require("distributed", "fleet", "phid fleet").as_completed

    with cluster(options.scheduler, options.workers, dashboard=options.dashboard) as client:
        _check_workers(client)
        if on_cluster:
            on_cluster(client)
        futures = {}
        for item, h in todo:
            record = str(item.record) if item.record is not None else None
            fut = client.submit(process_recording, item.unit, str(item.path), h, options.diagnose, record, pure=False)
            futures[fut] = (item, h)
        result.submitted = len(futures)
        for fut in as_completed(futures, loop=client.loop):
            item, h = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:  # a task that could not finish: the worker died under it every time
                row = Row(item.unit, str(item.path), h, "failed", __version__, error=_lost(exc))
                row.method_version = method_version()
            row.record, row.record_hash, row.design = str(item.record or ""), _record_hash(history, item), item.design
            _store(history, result, row, on_row, result.recordings - result.skipped)


def _check_workers(client: Client) -> None:
    """Every worker imports the task's code now, and runs this very phid version.

    On a remote cluster a worker with another phid (or none) would fill the history with rows
    a rerun cannot tell apart; refused before any task. On a local one this only moves the
    imports (about two seconds a worker) out of the first tasks.
    """
    try:
        versions = client.run(_worker_version)
    except Exception as exc:  # the worker cannot even unpickle the check: no phid_ros there
        raise PhidError(f"a Dask worker cannot run phid tasks: {one_line(exc)}") from None
    if not versions:
        raise PhidError(f"the Dask cluster at {getattr(client.scheduler, 'address', '?')} has no workers")
    wrong = {w: v for w, v in versions.items() if v != method_version()}
    if wrong:
        w, v = next(iter(wrong.items()))
        raise PhidError(
            f"Dask worker {w} runs {v}, this phid is {method_version()}: install the same phid_ros on every worker "
            f"({len(wrong)} of {len(versions)} differ)"
        )


def _worker_version() -> str:
    try:
        import phid_ros
        import phid_ros.api  # noqa: F401 - what every task needs, imported once per worker
    except ImportError as exc:
        return f"no usable phid_ros ({exc})"
    from phid_ros.provenance import method_version

    return method_version()


def _lost(exc: BaseException) -> str:
    from distributed import KilledWorker

    if isinstance(exc, KilledWorker):
        return "a Dask worker died under this task each time it was tried (memory? a crash?); rerun with --retry-failed"
    return one_line(exc)


def _store(
    history: History, result: FleetRun, row: Row, on_row: Callable[[Row, int, int], None] | None, total: int
) -> None:
    history.add(row)
    result.rows.append(row)
    if on_row:
        on_row(row, len(result.rows), total)
