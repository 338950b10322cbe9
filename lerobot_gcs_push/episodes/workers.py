"""One fan-out for demonstrations and evaluation: worker processes on this machine, or Ray actors on a cluster.

A pool is built from an initializer, run once in each worker to load what every job needs (the env, the
planner, a policy), and runs module-level functions `fn(job)` in those workers. Both backends run the same
initializer and the same functions: the work is identical, only where it runs differs.

- `process`: a concurrent.futures pool of forkserver processes. multiprocessing.Pool would silently replace
  a worker that dies (a crash in the renderer, the OOM killer) and wait forever for its job; this one reports
  the death, and we raise a RuntimeError. The other way round, a worker leaves when the driver is killed
  alone (`kill`, `timeout`): nothing would close its queue, and it would wait forever holding its memory.
  One worker runs the jobs in this process, without a pool.
- `ray`: one actor per worker (one CPU each) on the cluster at `address` (`auto` or `HOST:PORT`), or on a Ray
  started here when there is no address. Ray restarts an actor whose process dies and runs its job again, up
  to RETRIES times, so jobs must be idempotent (ours publish their results by atomic rename).
"""

from __future__ import annotations

import contextlib
import importlib.util
import multiprocessing as mp
import os
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

BACKENDS = ("process", "ray")
RETRIES = 3


@dataclass
class FanOut:
    """How a command's jobs fan out: the one definition of these settings, which `generate`, `evaluate`,
    `collect`, `demo` and `improve` take as theirs (`--workers`, `--backend`, `--ray_address`)."""

    # Worker processes (or Ray actors); the results do not depend on it (every job is seeded by itself).
    workers: int = 2
    # process (worker processes here) or ray (Ray actors; see lerobot_gcs_push.episodes.workers).
    backend: str = "process"
    # With backend ray: "auto" or "HOST:PORT" joins a running cluster; none starts Ray here.
    ray_address: str | None = None

    def check_fan_out(self) -> None:
        """For the configs' validation: fail before any work, with the fix in the message."""
        if self.workers < 1:
            raise ValueError(f"workers must be >= 1, got {self.workers}")
        check_backend(self.backend, self.ray_address)

    def fan_out(self) -> dict:
        """The settings as keywords, for the command this one runs."""
        return {"workers": self.workers, "backend": self.backend, "ray_address": self.ray_address}


def check_backend(backend: str, address: str | None) -> None:
    """For the configs' validation: fail before any work, with the fix in the message."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}: choose one of {BACKENDS}")
    if address is not None and backend != "ray":
        raise ValueError("ray_address needs backend ray")
    if backend == "ray" and importlib.util.find_spec("ray") is None:
        raise ValueError("--backend ray needs Ray: pip install 'lerobot_env_gcs_push[ray]'")


class Pool:
    """`submit` jobs, then take their results with `next` (as they finish) or `map`."""

    def __init__(self) -> None:
        self._tickets = 0

    def submit(self, fn: Callable, job: Any) -> int:
        ticket = self._tickets
        self._tickets += 1
        self._start(ticket, fn, job)
        return ticket

    def map(self, fn: Callable, jobs: Iterable) -> Iterator:
        """Submits every job, then yields the results as they finish."""
        tickets = [self.submit(fn, job) for job in jobs]
        for _ in tickets:
            yield self.next()[1]

    def next(self) -> tuple[int, Any]:
        """(ticket, result) of a finished job; a job's own exception is raised here."""
        raise NotImplementedError

    def _start(self, ticket: int, fn: Callable, job: Any) -> None:
        raise NotImplementedError

    def close(self) -> None:
        pass


class InlinePool(Pool):
    """Runs each job in this process when its result is asked for: no pool start-up, plain tracebacks."""

    def __init__(self, initializer: Callable, initargs: tuple):
        super().__init__()
        initializer(*initargs)
        self._queue: deque = deque()

    def _start(self, ticket, fn, job):
        self._queue.append((ticket, fn, job))

    def next(self):
        ticket, fn, job = self._queue.popleft()
        return ticket, fn(job)


class ProcessPool(Pool):
    def __init__(self, workers: int, initializer: Callable, initargs: tuple, hint: str):
        super().__init__()
        self._hint = hint
        self._executor = ProcessPoolExecutor(
            workers,
            mp_context=mp.get_context("forkserver"),
            initializer=_leave_with_driver,
            initargs=(os.getpid(), initializer, initargs),
        )
        self._futures: dict = {}  # future -> ticket

    def _start(self, ticket, fn, job):
        self._futures[self._executor.submit(fn, job)] = ticket

    def next(self):
        done, _ = wait(self._futures, return_when=FIRST_COMPLETED)
        future = min(done, key=self._futures.get)
        ticket = self._futures.pop(future)
        try:
            return ticket, future.result()
        except BrokenProcessPool as err:
            raise RuntimeError(f"a worker process died ({err}); {self._hint}") from err

    def close(self):
        # Jobs already running finish (a dead pool has none); queued ones never start.
        self._executor.shutdown(wait=True, cancel_futures=True)


def _leave_with_driver(driver: int, initializer: Callable, initargs: tuple) -> None:
    """A process worker's initializer: the job's own, and a thread that ends the worker once the driver is
    gone. Polled, since a forkserver worker's parent is the fork server, not the driver."""

    def watch() -> None:
        while True:
            time.sleep(1.0)
            try:
                os.kill(driver, 0)
            except (ProcessLookupError, PermissionError):  # gone, or its pid reused by another user
                os._exit(1)

    threading.Thread(target=watch, daemon=True, name="leave-with-driver").start()
    initializer(*initargs)


class RayWorker:
    """A Ray worker: the same initializer as a process-pool worker, then any number of jobs."""

    def __init__(self, initializer: Callable, initargs: tuple):
        initializer(*initargs)

    def run(self, fn: Callable, job: Any) -> Any:
        return fn(job)


class RayPool(Pool):
    """One job per actor at a time; the rest wait here, so a slow job never holds others in an actor's queue."""

    def __init__(self, workers: int, initializer: Callable, initargs: tuple, address: str | None, hint: str):
        super().__init__()
        import ray

        self._ray, self._hint = ray, hint
        self._owns_ray = not ray.is_initialized()  # a caller's own connection (tests, notebooks) is kept
        if self._owns_ray:
            # No dashboard for a Ray started here: on a laptop its processes would compete with the workers.
            ray.init(address=address, **({"include_dashboard": False} if address is None else {}))
        cpus = ray.cluster_resources().get("CPU", 0)
        if workers > cpus:
            self.close()
            # An actor that cannot be placed would wait forever, and its jobs with it.
            raise ValueError(
                f"{workers} workers need {workers} CPUs, but the Ray cluster has {cpus:g}: "
                f"pass --workers {int(cpus)} or add nodes"
            )
        actor = ray.remote(num_cpus=1, max_restarts=RETRIES, max_task_retries=RETRIES)(RayWorker)
        self._actors = [actor.remote(initializer, initargs) for _ in range(workers)]
        self._idle = list(self._actors)
        self._waiting: deque = deque()
        self._running: dict = {}  # ObjectRef -> (ticket, actor)

    def _start(self, ticket, fn, job):
        self._waiting.append((ticket, fn, job))
        self._dispatch()

    def _dispatch(self):
        while self._idle and self._waiting:
            ticket, fn, job = self._waiting.popleft()
            actor = self._idle.pop()
            self._running[actor.run.remote(fn, job)] = (ticket, actor)

    def next(self):
        [ref], _ = self._ray.wait(list(self._running), num_returns=1)
        ticket, actor = self._running.pop(ref)
        self._idle.append(actor)
        self._dispatch()
        try:
            return ticket, self._ray.get(ref)
        except self._ray.exceptions.RayActorError as err:
            raise RuntimeError(
                f"a Ray worker died and {RETRIES} restarts did not get its job done ({err}); {self._hint}"
            ) from err

    def close(self):
        for actor in getattr(self, "_actors", []):
            self._ray.kill(actor)
        if self._owns_ray:
            self._ray.shutdown()


@contextlib.contextmanager
def open_pool(
    backend: str, workers: int, initializer: Callable, initargs: tuple, *, address: str | None = None, hint: str = ""
) -> Iterator[Pool]:
    """The pool for `backend`; `hint` ends the message raised when a worker dies (what is kept, what to do)."""
    check_backend(backend, address)
    if backend == "ray":
        pool: Pool = RayPool(workers, initializer, initargs, address, hint)
    elif workers > 1:
        pool = ProcessPool(workers, initializer, initargs, hint)
    else:
        pool = InlinePool(initializer, initargs)
    try:
        yield pool
    finally:
        pool.close()
