"""Worker processes for a round's candidates: same answers as one process, and a safe fallback."""

from __future__ import annotations

import math
import os

from phid_ros.diagnose.parallel import Jobs


def test_jobs_in_worker_processes_give_the_answers_of_one_process_in_call_order():
    calls = [(float(a), float(b)) for a, b in ((3, 4), (5, 12), (8, 15), (7, 24))]
    with Jobs(2) as jobs:
        assert jobs.map(math.hypot, calls) == [5.0, 13.0, 17.0, 25.0]
        assert jobs.map(os.getpid, [(), ()]) != [os.getpid()] * 2  # really elsewhere
        assert jobs._pool is not None
    assert jobs._pool is None  # shut down on leaving


def test_a_job_that_cannot_be_sent_to_a_worker_runs_here():
    offset = 10.0
    with Jobs(2) as jobs:
        assert jobs.map(lambda x: x + offset, [(1.0,), (2.0,)]) == [11.0, 12.0]
        assert jobs._pool is None  # no worker was started for it


def test_one_worker_or_one_job_starts_no_process():
    with Jobs(1) as one:
        assert one.map(math.hypot, [(3.0, 4.0), (6.0, 8.0)]) == [5.0, 10.0]
        assert one._pool is None
    with Jobs(2) as two:
        assert two.map(math.hypot, [(3.0, 4.0)]) == [5.0]
        assert two._pool is None
