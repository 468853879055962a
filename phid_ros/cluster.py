"""How phid runs work in parallel: Dask distributed, or threads for compiled work.

A local cluster (one single-threaded worker *process* per core: a play-in or a
stage-3 fit is a Python loop over time steps whose numpy calls are too small to
release the GIL for long, so threads would not help) when no scheduler is named,
or an existing cluster by its scheduler address. Work that runs compiled without
the GIL (a diagnosis's play-ins in ``phid_ros.sim.kernel``) goes to a pool of
threads in this process instead when no cluster is named: the speed of processes
without their memory or the copies of the data. A thread pool, not an in-process
Dask cluster: on ``phid diagnose bags/saturation`` (two workers) the in-process
cluster's peak was 706 MB against the pool's 416 MB, in the same time. The fleet runs one recording per
task on it; a diagnosis runs a round's candidates on it, and when that diagnosis is
itself a fleet task its candidates go to the same cluster (``worker_client``), so
nothing here ever starts a second pool inside a worker.

Worker processes are spawned, not forked (Dask's default): the caller may hold
threads (a terminal progress display does) and a forked child can inherit their locks.
"""

from __future__ import annotations

import logging
import os
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import AbstractContextManager, ExitStack, contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

from phid_ros.errors import PhidError
from phid_ros.extras import installed, require

if TYPE_CHECKING:
    from distributed import Client

T = TypeVar("T")

CONNECT_TIMEOUT_S = 5.0  # an unreachable scheduler is an error within seconds, not a hang

# Dask starts its workers with MALLOC_TRIM_THRESHOLD_=65536 (memory back to the OS sooner).
# That fixes glibc's otherwise adaptive malloc thresholds, so every large numpy temporary of a
# play-in or a stage-3 fit is a fresh mmap with its page faults: an identification took 1.5 s
# in a worker against 0.7 s in a plain process (bench_fleet.py). None: glibc's defaults.
LOCAL_WORKER_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}


class ClusterError(PhidError):
    """The Dask cluster could not be reached or started."""


def default_workers() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


_running = 0  # calls of Jobs' thread pools running now in this process
_running_lock = threading.Lock()
_here = threading.local()  # .job: this thread is running one of them


def spare_threads() -> int:
    """How many threads one compiled call may split over now: its own and the cores no job holds.

    Outside a pool of job threads every core; inside one, the calling job's own thread plus the
    cores whose threads have run out of jobs (the last, longest candidate of a round gets the
    core the others have left). 1 in a Dask worker process: its sibling workers hold the others.
    """
    if in_worker():
        return 1
    with _running_lock:
        free = default_workers() - _running
    return max(1, free + (1 if getattr(_here, "job", False) else 0))


def _as_job(fn: Callable[..., T], args: tuple[Any, ...]) -> T:
    """``fn(*args)`` counted as a running job (see :func:`spare_threads`)."""
    global _running
    with _running_lock:
        _running += 1
    _here.job = True
    try:
        return fn(*args)
    finally:
        _here.job = False
        with _running_lock:
            _running -= 1


@dataclass(frozen=True)
class ClusterInfo:
    scheduler: str
    workers: int
    local: bool
    dashboard: str | None  # None: not served (bokeh missing, or a remote cluster without one)


LOOPBACK = "127.0.0.1"


@contextmanager
def cluster(scheduler: str | None = None, workers: int = 0, *, dashboard: bool = False) -> Iterator[Client]:
    """A Dask client: on the scheduler at ``scheduler``, or on a new local cluster of ``workers`` processes.

    ``workers`` 0 means one per core. The local cluster's dashboard is served on a free loopback
    port when ``dashboard`` is set and bokeh is installed. The client and a local
    cluster are closed on leaving.
    """
    dask = require("dask", "fleet", "a Dask cluster")
    distributed = require("distributed", "fleet", "a Dask cluster")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster

    with ExitStack() as stack:
        if scheduler:
            try:
                client = Client(scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
            except (OSError, TimeoutError, ValueError) as exc:
                raise ClusterError(
                    f"--scheduler {scheduler}: no Dask scheduler answered within {CONNECT_TIMEOUT_S:g} s "
                    f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else 'no detail'})"
                ) from None
            stack.callback(client.close)
        else:
            n = workers if workers > 0 else default_workers()
            serve = dashboard and _bokeh_available()
            with dask.config.set(LOCAL_WORKER_CONFIG):
                local = LocalCluster(
                    n_workers=n,
                    threads_per_worker=1,
                    processes=True,
                    # loopback only, scheduler and dashboard: ":0" bound every interface and answered
                    # on the LAN address while the log printed a loopback URL
                    host=LOOPBACK,
                    dashboard_address=f"{LOOPBACK}:0" if serve else None,
                    silence_logs=logging.ERROR,
                )
            stack.callback(local.close)
            client = Client(local, set_as_default=False)
            stack.callback(client.close)
        yield client


def describe(client: Client) -> ClusterInfo:
    """Where the work goes, for the user: scheduler address, worker count, dashboard link."""
    info = client.scheduler_info()
    local = client.cluster is not None
    link: str | None = None
    if "dashboard" in info.get("services", {}):
        link = client.dashboard_link
    return ClusterInfo(info.get("address", str(client.scheduler)), len(info.get("workers", {})), local, link)


def _bokeh_available() -> bool:
    try:
        import bokeh  # noqa: F401  (the dashboard's only extra requirement)
    except ImportError:
        return False
    return True


def in_worker() -> bool:
    """Whether this code runs inside a Dask worker (a fleet task)."""
    if "distributed" not in sys.modules:  # a worker process has it imported; asking would import it (0.3 s)
        return False
    try:
        from distributed import get_worker
    except ImportError:
        return False
    try:
        get_worker()
    except ValueError:
        return False
    return True


# glibc's mallopt parameters
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD, M_ARENA_MAX = -1, -3, -8
MMAP_THRESHOLD_BYTES = 64 << 20
TRIM_THRESHOLD_BYTES = 256 << 20


def tune_malloc() -> bool:
    """glibc's allocator set for a process of many short-lived arrays of a few MB.

    - One arena for every thread (M_ARENA_MAX 1). glibc gives each thread that allocates its
      own arena (up to eight per core), and an arena keeps its high-water mark. The diagnosis's
      job threads and the play-in's column threads each allocate tens of MB of trajectories
      and residuals per evaluation: with an arena each, ``phid diagnose bags/saturation``
      peaked at 440-460 MB; with one, at about 360 MB and no slower.
    - Arrays below 64 MB from the heap, and the heap's top returned to the system only above
      256 MB free (M_MMAP_THRESHOLD, M_TRIM_THRESHOLD). By default a 1 MB array is mapped
      fresh and unmapped when freed, so the next one faults its 256 pages in again: on these
      virtual machines a page fault costs microseconds, and a stage-3 filter of an (18, 8000)
      array spent 1.1 of its 1.8 ms in them. Warm ``phid identify`` of the catalogue: 16 000
      page faults per run -> 1 500, 0.95 -> 0.86 s. (Forcing arrays onto mmap instead, a 1 MB
      threshold, cut the diagnosis's peak to 330 MB but cost it 30 % in faults.)

    Linux with glibc only; elsewhere nothing changes (False).
    """
    if not sys.platform.startswith("linux"):
        return False
    import ctypes

    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):  # not glibc (musl has no mallopt arenas)
        return False
    settings = ((M_ARENA_MAX, 1), (M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES), (M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))
    return all([bool(mallopt(key, value)) for key, value in settings])


# the BLAS libraries' thread counts, for a library loaded after one_blas_thread is entered
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread() -> AbstractContextManager[Any]:
    """One BLAS thread for the work inside (every command, node and diagnosis runs in it).

    phid's matrices are small (a stage's normal equations, a control fit's Jacobian of a few
    hundred rows): a second BLAS thread costs more to wake than it saves, and OpenBLAS's idle
    threads spin, so beside any other busy thread (a second job, a second process) they take
    its core. The Mostar day's replay: 33 s with numpy's two threads on two cores, 17.7 s with
    one; two replays at once, 71.6 s against 17.5 s. OpenBLAS also rounds differently with
    another thread count, so with one the digits do not depend on the machine's cores.
    """
    for name in BLAS_THREAD_VARIABLES:
        os.environ[name] = "1"
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


class Jobs(AbstractContextManager["Jobs"]):
    """Independent calls of one function, on a Dask cluster when that pays and is possible.

    ``workers`` 1 runs everything here. Otherwise: inside a Dask worker the calls go to
    that worker's own cluster (the worker secedes while it waits, so a two-worker cluster
    cannot deadlock on its own tasks); elsewhere to ``scheduler``; else, with ``threads``
    (calls that run without the GIL), to ``workers`` threads here (0: one per core); else
    to a local cluster of ``workers`` processes (0: one per core) started on first use and
    kept until the context is left. A call whose arguments cannot be sent to another
    interpreter runs here; the answer is the same, only slower. Without the ``[fleet]`` extra
    (no Dask) and no ``scheduler``, the calls that would have gone to a local cluster run here
    too: Dask is an extra, and a diagnosis must not need it.
    """

    def __init__(self, workers: int, scheduler: str | None = None, *, threads: bool = False) -> None:
        self.workers = workers
        self.scheduler = scheduler
        self.threads = threads
        self._stack: ExitStack | None = None
        self._client: Client | None = None

    def map(self, fn: Callable[..., T], calls: Sequence[tuple[Any, ...]]) -> list[T]:
        """``[fn(*args) for args in calls]``, in call order."""
        if self.workers == 1 or len(calls) <= 1:
            return [fn(*args) for args in calls]
        if self.threads and not self.scheduler and not in_worker():
            n = min(len(calls), self.workers if self.workers > 0 else default_workers())
            # one BLAS thread per job thread: OpenBLAS's own threads on top oversubscribed the
            # cores and spin while they wait (bags/saturation, 2 workers: 25.3 s, 45.9 s of CPU;
            # with this 18.3 s, 30.4 s of CPU)
            pool = ThreadPoolExecutor(n, "phid-jobs")
            try:
                with one_blas_thread():
                    return list(pool.map(lambda args: _as_job(fn, args), calls))
            finally:
                # on an error or Ctrl-C the jobs not yet started are dropped, not run to the end first
                pool.shutdown(wait=True, cancel_futures=True)
        if not self.scheduler and not installed("fleet"):
            return [fn(*args) for args in calls]
        if not _portable(fn, calls):
            return [fn(*args) for args in calls]
        if in_worker():
            from distributed import worker_client

            with worker_client() as client:
                return _gather(client, fn, calls)
        if self._client is None:
            self._stack = ExitStack()
            self._client = self._stack.enter_context(cluster(self.scheduler, self.workers))
        return _gather(self._client, fn, calls)

    def __exit__(self, *exc: object) -> None:
        if self._stack is not None:
            self._stack.close()
        self._stack = None
        self._client = None


def _gather(client: Client, fn: Callable[..., T], calls: Sequence[tuple[Any, ...]]) -> list[T]:
    # pure=False: two calls with equal arguments are still two calls (a candidate's screen
    # depends on state the arguments do not show, e.g. a random start)
    futures = [client.submit(fn, *args, pure=False) for args in calls]
    return client.gather(futures)


def _portable(fn: Callable[..., Any], calls: Sequence[tuple[Any, ...]]) -> bool:
    """Whether another interpreter can rebuild the call (Dask sends it with cloudpickle)."""
    import cloudpickle

    try:
        cloudpickle.dumps((fn, calls))
    except Exception:  # cloudpickle raises whatever the object's __reduce__ raises
        return False
    return True
