"""The Dask engine (phid_ros.cluster): same answers as one process, a safe fallback, clear errors."""

from __future__ import annotations

import math
import os
import threading
import time

import pytest

from phid_ros.cluster import ClusterError, Jobs, cluster


def test_jobs_on_dask_workers_give_the_answers_of_one_process_in_call_order():
    calls = [(float(a), float(b)) for a, b in ((3, 4), (5, 12), (8, 15), (7, 24))]
    with Jobs(2) as jobs:
        assert jobs.map(math.hypot, calls) == [5.0, 13.0, 17.0, 25.0]
        pids = jobs.map(os.getpid, [(), (), (), ()])
        assert os.getpid() not in pids  # really in other processes
        assert jobs._client is not None
        offset = 10.0  # a closure travels too (cloudpickle)
        assert jobs.map(lambda x: x + offset, [(1.0,), (2.0,)]) == [11.0, 12.0]
    assert jobs._client is None  # cluster shut down on leaving


def _locked(lock: object, x: float) -> float:
    return x + 1.0


def test_a_job_that_cannot_be_sent_to_a_worker_runs_here():
    lock = threading.Lock()  # no interpreter but this one can have it
    with Jobs(2) as jobs:
        assert jobs.map(_locked, [(lock, 1.0), (lock, 2.0)]) == [2.0, 3.0]
        assert jobs._client is None  # no cluster was started for it


def test_one_worker_or_one_job_starts_no_cluster():
    with Jobs(1) as one:
        assert one.map(math.hypot, [(3.0, 4.0), (6.0, 8.0)]) == [5.0, 10.0]
        assert one._client is None
    with Jobs(2) as two:
        assert two.map(math.hypot, [(3.0, 4.0)]) == [5.0]
        assert two._client is None


def test_an_unreachable_scheduler_is_a_clear_error_within_seconds():
    t0 = time.perf_counter()
    with pytest.raises(ClusterError, match=r"--scheduler tcp://127\.0\.0\.1:9: no Dask scheduler answered within 5 s"):
        with cluster("tcp://127.0.0.1:9"):
            pass
    assert time.perf_counter() - t0 < 15.0


def test_jobs_and_the_cluster_context_use_an_existing_cluster_by_its_address():
    from distributed import LocalCluster

    from phid_ros.cluster import describe

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as existing:
        with cluster(existing.scheduler_address) as client:
            info = describe(client)
            assert (info.scheduler, info.workers, info.local) == (existing.scheduler_address, 1, False)
        with Jobs(0, scheduler=existing.scheduler_address) as jobs:
            assert jobs.map(math.hypot, [(3.0, 4.0), (5.0, 12.0)]) == [5.0, 13.0]
        assert len(existing.scheduler.workers) == 1  # the cluster outlives its clients


def test_jobs_on_threads_run_here_in_call_order_and_hand_free_cores_to_the_last_job():
    """threads=True: a pool of threads in this process (no cluster); a job's compiled calls may
    use its own thread plus every core no other job holds."""
    from phid_ros import cluster as cl

    started, measured = threading.Barrier(2), threading.Barrier(2)

    def job(i: int) -> tuple[int, int, str]:
        if i < 2:
            started.wait(timeout=10)  # both running: neither may take the other's core
            spare = cl.spare_threads()
            measured.wait(timeout=10)
        else:
            deadline = time.monotonic() + 10
            while cl._running > 1 and time.monotonic() < deadline:  # until the other thread runs out of jobs
                time.sleep(0.01)
            spare = cl.spare_threads()
        return i, spare, threading.current_thread().name

    with Jobs(2, threads=True) as jobs:
        out = jobs.map(job, [(0,), (1,), (2,)])
        assert jobs._client is None
    assert [i for i, _, _ in out] == [0, 1, 2]
    assert all(name.startswith("phid-jobs") for _, _, name in out)
    cores = cl.default_workers()
    assert [s for _, s, _ in out] == [max(1, cores - 1), max(1, cores - 1), cores]
    assert cl.spare_threads() == cores  # no job running: every core


def test_a_failing_job_on_threads_raises_and_the_jobs_not_yet_started_are_dropped():
    ran: list[int] = []

    def job(i: int) -> int:
        ran.append(i)
        if i == 0:
            raise ValueError("job 0 failed")
        time.sleep(0.2)
        return i

    with Jobs(2, threads=True) as jobs, pytest.raises(ValueError, match="job 0 failed"):
        jobs.map(job, [(i,) for i in range(20)])
    time.sleep(0.3)
    # job 0, the job beside it and the few that start before the main thread wakes (3 on a quiet
    # machine); the pool without cancel_futures ran all 20 (0.2 s each) before raising
    assert len(ran) < 10


def test_the_cli_process_tunes_glibc_malloc():
    # the diagnosis's threads shared glibc's arenas badly: 440-460 MB peak with one per thread
    import platform
    import sys

    from phid_ros.cluster import tune_malloc

    assert tune_malloc() is (sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc")


def test_the_local_cluster_and_its_dashboard_listen_on_loopback_only():
    """``dashboard_address=":0"`` bound every interface and answered on the LAN address while the
    log printed a loopback URL. Every socket the local cluster opens is now on 127.0.0.1."""
    import socket

    pytest.importorskip("bokeh")
    from phid_ros.cluster import describe

    with cluster(workers=1, dashboard=True) as client:
        info = describe(client)
        assert info.dashboard is not None and "127.0.0.1" in info.dashboard
        scheduler = client.cluster.scheduler
        bound = [s.getsockname()[0] for s in scheduler.http_server._sockets.values()]
        bound += [socket.getaddrinfo(scheduler.address.split("//")[1].rsplit(":", 1)[0], None)[0][4][0]]
        workers = client.scheduler_info()["workers"]
        bound += [a for w, d in workers.items() for a in (w, d.get("nanny") or w)]
        bound = [a.removeprefix("tcp://").rsplit(":", 1)[0] for a in bound]
        assert bound and all(a in ("127.0.0.1", "::1") for a in bound), bound
