"""The process pool of `workers.py` without Ray: every result comes back once under its ticket, and a worker
that dies is reported with the caller's hint instead of being waited for. The Ray pool on a real cluster
(test_ray.py) and workers leaving a killed driver (test_evaluation.py) are in the slow tier."""

from __future__ import annotations

import os

import pytest

from lerobot_gcs_push.episodes.workers import InlinePool, ProcessPool, open_pool


def test_two_worker_processes_return_every_result_once_under_its_ticket():
    jobs = [-3, 5, -8, 0, 13, -21]
    with open_pool("process", 2, int, ()) as pool:
        assert isinstance(pool, ProcessPool)
        tickets = {pool.submit(abs, job): job for job in jobs}
        got = dict(pool.next() for _ in jobs)
        assert sorted(pool.map(abs, [-7, 8])) == [7, 8]
    assert got == {ticket: abs(job) for ticket, job in tickets.items()}
    with open_pool("process", 1, int, ()) as pool:  # one worker: the jobs run in this process
        assert isinstance(pool, InlinePool) and list(pool.map(abs, [-2, 3])) == [2, 3]


def test_a_worker_process_that_dies_is_reported_with_the_hint():
    with open_pool("process", 2, int, (), hint="HINT") as pool, pytest.raises(RuntimeError, match="(?s)died.*HINT"):
        list(pool.map(os._exit, [1]))
