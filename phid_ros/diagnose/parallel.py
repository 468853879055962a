"""Independent candidate jobs on every core.

A diagnosis round screens and fits each candidate against the same current model;
the jobs share nothing, so they run in worker processes (each play-in is a Python
loop over time steps whose numpy calls are too small to release the GIL for long,
so threads would not help). Workers are *spawned*, not forked: the caller may hold
threads (a terminal progress display does) and a forked child can inherit their locks.

A job whose arguments cannot be sent to a fresh interpreter (a candidate made at run
time for an effect registered at run time, as a test does) runs in this process
instead; the answer is the same, only slower.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import AbstractContextManager
from typing import Any, TypeVar

T = TypeVar("T")


def default_workers() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


class Jobs(AbstractContextManager["Jobs"]):
    """A pool of ``workers`` processes, started on first use and kept for the whole diagnosis."""

    def __init__(self, workers: int) -> None:
        self.workers = workers if workers > 0 else default_workers()
        self._pool: Executor | None = None

    def map(self, fn: Callable[..., T], calls: Sequence[tuple[Any, ...]]) -> list[T]:
        """``[fn(*args) for args in calls]``, in worker processes when that pays and is possible."""
        if self.workers <= 1 or len(calls) <= 1 or not _portable(fn, calls):
            return [fn(*args) for args in calls]
        if self._pool is None:
            self._pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("spawn"))
        futures = [self._pool.submit(fn, *args) for args in calls]
        return [f.result() for f in futures]

    def __exit__(self, *exc: object) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def _portable(fn: Callable[..., Any], calls: Sequence[tuple[Any, ...]]) -> bool:
    """Whether a spawned interpreter can rebuild the job: everything pickles by importable name."""
    try:
        pickle.dumps((fn, calls))
    except (pickle.PicklingError, AttributeError, TypeError):
        return False
    return True
