"""The bounded thread lane: where an HTTP process runs its own designs (the closed forms) and fits.

Closed-form families need no solver, so they run in the HTTP process, off the event loop; this lane bounds
that work the way ``runtime.pool.SolverPool`` bounds the solves:

- at most ``workers`` jobs compute at once (one per core by default), each in a thread of the lane's own
  executor (never starlette's shared thread pool, which takes up to 40 jobs);
- at most ``max_queued`` jobs wait for a thread; a job beyond that is refused at once (``PoolBusy``, the pool's
  503 ``busy`` with Retry-After), and so is a job that waits its whole deadline for a thread;
- a job that computes past its deadline is answered ``WorkTimeout`` (a 504 ``solve-timeout``) at once. A thread
  cannot be stopped, so it finishes in the background, its work bounded by the sample caps
  (``VIBFREE_MAX_SAMPLES``, the families' own), and keeps its place among the ``workers`` until then: no more
  than ``workers`` threads ever compute, however many requests time out.

The lane holds no event loop (a concurrent.futures executor and a lock), so one lane serves every loop of the
process; ``stats()`` gives its counts for /readyz and /metrics.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import logging
import math
import threading
import time
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any, TypeVar

from models.errors import PoolUnavailable, SolverTimedOut
from runtime.executor import (
    RETRY_AFTER_MAX_S,
    RETRY_AFTER_MIN_S,
    Executor,
    HeldPlaces,
    PoolBusy,
    report_change,
    reservation_places,
)
from runtime.heap import release_free_heap

log = logging.getLogger(__name__)
T = TypeVar("T")


class WorkTimeout(SolverTimedOut):
    """A design (or fit) in the HTTP process computed past its deadline; its thread finishes in the background."""

    def __init__(self, limit_s: float) -> None:
        self.limit_s = limit_s
        super().__init__(None, f"the design did not finish within {limit_s:g} s")

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.limit_s,))


class ThreadLane:
    """A bounded executor for the HTTP process's own work: ``workers`` threads, ``max_queued`` waiting, deadlines."""

    def __init__(
        self,
        workers: int,
        max_queued: int,
        *,
        on_change: Callable[[dict[str, int]], None] | None = None,
    ) -> None:
        if workers < 1 or max_queued < 0:
            raise ValueError("a thread lane needs at least one thread and a queue limit >= 0")
        self.workers = workers
        self.max_queued = max_queued
        self.on_change = on_change  # called with stats() after every change of state (the metrics' files)
        self._executor = concurrent.futures.ThreadPoolExecutor(workers, thread_name_prefix="vibfree-design")
        self._lock = threading.Lock()
        self._queued = 0
        self._running = 0
        self._held = 0  # places reserved by requests (reserve) and not taken by one of their jobs now
        self._overrunning = 0  # running past their deadline: their requests were answered 504
        self._closed = False
        self._job_s_estimate = 0.1  # running mean of job times, for Retry-After
        self.timeouts = 0
        self.rejected = 0

    def stats(self) -> dict[str, int]:
        """Counts for /readyz and /metrics."""
        with self._lock:
            return {
                "threads": self.workers,
                "running": self._running,
                "queued": self._queued,
                "held": self._held,
                "overrunning": self._overrunning,
                "timeouts": self.timeouts,
                "rejected": self.rejected,
            }

    def _changed(self) -> None:
        report_change(self.on_change, self.stats, log)

    def retry_after_s(self) -> int:
        """When a thread is likely to free: the mean job time times the jobs ahead per thread."""
        ahead = (self._queued + 1) / self.workers
        return int(min(RETRY_AFTER_MAX_S, max(RETRY_AFTER_MIN_S, math.ceil(self._job_s_estimate * ahead))))

    def close(self) -> None:
        """Refuse new jobs and drop the waiting ones; running threads finish on their own."""
        with self._lock:
            self._closed = True
        self._executor.shutdown(wait=False, cancel_futures=True)

    def _admit(self, jobs: int) -> None:
        """Count ``jobs`` more places (waiting or held), all or none: ``PoolBusy`` when the lane has no room."""
        with self._lock:
            if self._closed:
                raise PoolUnavailable("the service is shutting down")
            if self._running + self._queued + self._held + jobs > self.workers + self.max_queued:
                self.rejected += jobs
                what = "design" if jobs == 1 else f"the {jobs} designs"
                busy = PoolBusy(
                    f"every design thread is busy and {self._queued + self._held} designs are waiting or held "
                    f"(the most allowed): no room for {what}",
                    retry_after_s=self.retry_after_s(),
                )
            else:
                busy = None
                self._queued += jobs
        if busy is not None:
            self._changed()
            raise busy

    async def run(self, fn: Callable[..., T], *args: Any, deadline_s: float) -> T:
        """``fn(*args)`` in one of the lane's threads, within ``deadline_s`` of waiting and ``deadline_s`` of work."""
        self._admit(1)
        return await self._submit(fn, args, deadline_s, wait_s=deadline_s)

    @asynccontextmanager
    async def reserve(self, jobs: int) -> AsyncIterator[Executor]:
        """Hold places for ``jobs`` concurrent jobs of one request, all or none (``SolverPool.reserve``'s rule for
        the lane): as many as the lane has threads at most (``reservation_places``), the request's other jobs
        waiting for one of its places; refused at once (``PoolBusy``) without room, so a compare never runs part
        of its closed forms and is then refused for the rest. A held job waits for a thread a deadline per round
        of the jobs ahead of it (they were admitted first), not a lone job's single deadline."""
        places = reservation_places(jobs, self.workers)
        self._admit(places)
        with self._lock:
            self._queued -= places
            self._held += places
        reservation = _LaneReservation(self, places)
        self._changed()
        try:
            yield reservation
        finally:
            with self._lock:
                self._held -= reservation.free
                reservation.free = 0
                reservation.closed = True
            self._changed()

    def turns_ahead(self) -> int:
        """Deadlines a job queued now may wait for a thread: one per round of the jobs ahead of it, plus one."""
        with self._lock:
            return 1 + math.ceil((self._running + self._queued) / self.workers)

    async def _submit(self, fn: Callable[..., T], args: tuple[Any, ...], deadline_s: float, *, wait_s: float) -> T:
        """Run an admitted job (counted in ``_queued``): wait at most ``wait_s`` for a thread, ``deadline_s`` in it."""
        loop = asyncio.get_running_loop()
        started: asyncio.Future[float] = loop.create_future()
        job = _LaneJob()

        def tell_started(at: float) -> None:
            if not started.done():
                started.set_result(at)

        def work() -> T:
            at = time.monotonic()
            with self._lock:
                self._queued -= 1
                self._running += 1
                job.state = "running"
            self._changed()
            with contextlib.suppress(RuntimeError):  # the caller's loop has closed: nobody waits for the answer
                loop.call_soon_threadsafe(tell_started, at)
            try:
                return fn(*args)
            finally:
                with self._lock:
                    self._running -= 1
                    self._overrunning -= job.overran
                    job.state = "finished"
                    self._job_s_estimate += 0.2 * (time.monotonic() - at - self._job_s_estimate)
                self._changed()

        try:
            future = self._executor.submit(work)
        except RuntimeError:  # shut down between the check and the submission
            with self._lock:
                self._queued -= 1
            raise PoolUnavailable("the service is shutting down") from None
        answer = asyncio.wrap_future(future, loop=loop)
        # The job's intermediates, which glibc would keep in the thread's arena, given back once the answer is on its
        # way: this callback runs in the thread after the loop was told (wrap_future's callback came first).
        future.add_done_callback(_give_back_heap)
        answer.add_done_callback(_consume)  # an answer nobody awaits any more (a 504) is not logged as lost
        try:
            either: set[asyncio.Future[Any]] = {started, answer}
            done, _ = await asyncio.wait(either, timeout=wait_s, return_when=asyncio.FIRST_COMPLETED)
            if not done:
                if self._drop(job, future):  # still waiting for a thread: it never runs
                    with self._lock:
                        self.rejected += 1
                    self._changed()
                    raise PoolBusy(
                        f"no design thread became free within {wait_s:g} s",
                        retry_after_s=self.retry_after_s(),
                    )
                await started  # it started just now
            if not answer.done():
                remaining = deadline_s - (time.monotonic() - started.result())
                finished, _ = await asyncio.wait({answer}, timeout=max(remaining, 0.0))
                if not finished:
                    with self._lock:
                        self.timeouts += 1
                        if job.state == "running":
                            job.overran = 1
                            self._overrunning += 1
                    self._changed()
                    raise WorkTimeout(deadline_s)
            return answer.result()
        finally:
            if not answer.done() and self._drop(job, future):  # the caller went away while the job waited
                self._changed()

    def _drop(self, job: _LaneJob, future: concurrent.futures.Future[Any]) -> bool:
        """Cancel a job that still waits for a thread (True), once; False when it has started."""
        with self._lock:
            if job.state != "queued" or not future.cancel():
                return False
            job.state = "dropped"
            self._queued -= 1
            return True


class _LaneReservation(HeldPlaces):
    """Places held in the lane (``ThreadLane.reserve``): a held place becomes the job's queue place, and returns
    when the job ends."""

    def __init__(self, lane: ThreadLane, places: int) -> None:
        super().__init__(places)
        self.lane = lane

    def _take(self) -> None:
        with self.lane._lock:
            self.free -= 1
            self.lane._held -= 1
            self.lane._queued += 1

    def _give_back(self) -> None:
        with self.lane._lock:
            if not self.closed:
                self.free += 1
                self.lane._held += 1

    async def _run_alone(self, fn: Callable[..., T], args: tuple[Any, ...], deadline_s: float) -> T:
        return await self.lane.run(fn, *args, deadline_s=deadline_s)

    async def _run_held(self, fn: Callable[..., T], args: tuple[Any, ...], deadline_s: float) -> T:
        return await self.lane._submit(fn, args, deadline_s, wait_s=deadline_s * self.lane.turns_ahead())


class _LaneJob:
    """One job's place in the lane, changed under the lane's lock."""

    __slots__ = ("overran", "state")

    def __init__(self) -> None:
        self.state = "queued"  # then running and finished, or dropped while queued
        self.overran = 0  # 1 once its request was answered 504 while it ran


def _give_back_heap(_: concurrent.futures.Future[Any]) -> None:
    release_free_heap()


def _consume(future: asyncio.Future[Any]) -> None:
    if not future.cancelled():
        future.exception()
