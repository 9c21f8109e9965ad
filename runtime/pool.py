"""The supervised solver worker pool.

IPOPT with MUMPS is not thread-safe, so every CasADi solve runs in a worker process, never on the
event loop or in a thread. Each worker builds its solvers once, when it starts (the families'
warm-ups, ``optim.registry.warm_up_all``), and keeps them in its module-level caches.

The pool supervises its own processes (``runtime.pool_workers``), one pipe each, watched from the event
loop (``loop.add_reader`` on the pipe and on the process sentinel), so that

- any worker death (idle, busy or during its warm-up) is seen at once and that worker alone is
  replaced; a warm-up that fails or overruns ``start_timeout_s`` is retried with exponential
  back-off (0.5 s doubling to 30 s);
- a solve that overruns its deadline kills only its own worker; the other solves continue;
- the deadline counts solving time only: it starts when a worker takes the job;
- admission is bounded: at most ``max_queued`` jobs wait for a worker, a job beyond that is refused
  at once (``PoolBusy``, a 503 with Retry-After), and no job waits longer than its own deadline;
- a request that needs several jobs reserves them all at once (``reserve``): either each gets a place
  (a worker or a queue slot) held for it, or none does and the request is refused before any of its
  jobs ran;
- ``ready`` is true while at least one worker is warm, and ``stats()`` tells the rest.

Why not ``pebble.ProcessPool`` (tried, 5.2.3): a worker that dies while no task runs makes it raise
``BrokenProcessPool("All workers expired")`` and the whole pool stops for good; it has no signal of a
worker's warm-up being done (readiness) and counts nothing we could export. ``concurrent.futures``
cannot kill one worker at all. Supervising processes directly is about as long as the wrapper
either would need.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections import deque
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any, TypeVar

from models.errors import PoolUnavailable
from runtime.executor import (
    RETRY_AFTER_MAX_S,
    RETRY_AFTER_MIN_S,
    Executor,
    HeldPlaces,
    PoolBusy,
    SolveTimeout,
    report_change,
    reservation_places,
)
from runtime.pool_workers import PoolJob, PoolWorker, WorkerSupervisor

log = logging.getLogger(__name__)
T = TypeVar("T")

SETTLE_POLL_S = 0.02  # how often a reservation's exit looks whether its cancelled solves have left the workers


class _Reservation(HeldPlaces):
    """Places held in the solver pool (``SolverPool.reserve``)."""

    def __init__(self, pool: SolverPool, places: int) -> None:
        super().__init__(places)
        self.pool = pool
        self.jobs: set[PoolJob] = set()  # every job it submitted: those still in a worker are waited for on exit

    def _take(self) -> None:
        self.free -= 1
        self.pool._held -= 1

    def _give_back(self) -> None:
        self.free += 1
        self.pool._held += 1

    async def _run_alone(self, fn: Callable[..., T], args: tuple[Any, ...], deadline_s: float) -> T:
        return await self.pool.run(fn, *args, deadline_s=deadline_s)

    async def _run_held(self, fn: Callable[..., T], args: tuple[Any, ...], deadline_s: float) -> T:
        wait_s = deadline_s * self.pool.turns_ahead()
        return await self.pool._submit(fn, args, deadline_s, wait_s=wait_s, track=self.jobs)


class SolverPool(WorkerSupervisor):
    """A supervised process pool with readiness, admission control and per-solve deadlines."""

    def __init__(
        self,
        workers: int,
        start_timeout_s: float = 120.0,
        warm_up: Callable[[], None] | None = None,
        *,
        max_queued: int | None = None,
        niceness: int = 0,
        on_change: Callable[[dict[str, int]], None] | None = None,
        memory_mb: int = 0,
    ) -> None:
        super().__init__(workers, start_timeout_s, warm_up, niceness, memory_mb)
        self.on_change = on_change  # called with stats() after every change of state (the metrics' files)
        self.max_queued = 4 * workers if max_queued is None else max_queued
        self._queue: deque[PoolJob] = deque()
        self._held = 0  # places reservations hold that none of their jobs fills now (see reserve)
        self.timeouts = 0
        self.rejected = 0

    # --- state ---------------------------------------------------------------------------

    def stats(self) -> dict[str, int]:
        """Counts for /readyz and /metrics."""
        states = [w.state for w in self._workers]
        busy = states.count("busy")
        return {
            "workers": self.workers,
            "ready": busy + states.count("idle"),
            "busy": busy,
            "starting": states.count("starting") + len(self._respawns),
            "queued": len(self._queue),
            "restarts": self.restarts,
            "timeouts": self.timeouts,
            "rejected": self.rejected,
        }

    def _changed(self) -> None:
        report_change(self.on_change, self.stats, log)

    # --- stop ---------------------------------------------------------------------------

    async def close(self) -> None:
        """Stop the workers: let them exit (a second at most), then kill what is left."""
        self._closing = True
        for handle in self._respawns:
            handle.cancel()
        self._respawns.clear()
        while self._queue:
            job = self._queue.popleft()
            self._fail(job, PoolUnavailable("the service is shutting down"))
        workers, self._workers = self._workers, []
        for worker in workers:
            self._detach(worker)
            with contextlib.suppress(OSError, ValueError):
                worker.conn.send(None)
        deadline = time.monotonic() + 1.0
        for worker in workers:
            await asyncio.to_thread(worker.process.join, max(0.0, deadline - time.monotonic()))
            if worker.process.is_alive():
                worker.process.kill()
                await asyncio.to_thread(worker.process.join, 1.0)
            if worker.job is not None:
                self._fail(worker.job, PoolUnavailable("the service is shutting down"))
            with contextlib.suppress(OSError):
                worker.conn.close()
        self._ready_event.clear()
        self._changed()

    # --- jobs ----------------------------------------------------------------------------

    async def run(self, fn: Callable[..., T], *args: Any, deadline_s: float) -> T:
        """Run ``fn(*args)`` in a worker, within ``deadline_s`` of solving (and of waiting for a worker)."""
        self._admit(1)
        return await self._submit(fn, args, deadline_s)

    def _admit(self, jobs: int) -> None:
        """Refuse at once unless ``jobs`` more jobs have room: a worker or a queue slot each, beside the places
        reservations hold."""
        if self._closing or self._loop is None:
            raise PoolUnavailable("the solver pool is not running")
        if not self.ready and not self._recovering:
            raise PoolUnavailable("the solver workers are starting")  # Retry-After: the default 5 s
        if self._room() < jobs:
            self.rejected += jobs
            self._changed()
            waiting = f"{len(self._queue)} solves are waiting" + (f", {self._held} places held" if self._held else "")
            raise PoolBusy(
                f"every solver worker is busy and {waiting} (the most allowed)"
                if jobs == 1
                else f"no room for the {jobs} solves of the request: {waiting}, {self.max_queued} allowed",
                retry_after_s=self.retry_after_s(jobs),
            )

    def _room(self) -> int:
        """Jobs the pool can take now: its warm workers and ``max_queued`` queue slots, less the jobs they hold
        (running or queued) and the places reservations hold. With no reservation this is the rule "an idle
        worker, or fewer than ``max_queued`` waiting". A worker being replaced counts as warm (``_capacity``)."""
        busy = sum(worker.state == "busy" for worker in self._workers)
        return self._capacity() + self.max_queued - busy - len(self._queue) - self._held

    @asynccontextmanager
    async def reserve(self, jobs: int) -> AsyncIterator[Executor]:
        """Hold room for ``jobs`` concurrent jobs of one request, all or none, and yield the executor that runs
        them (``_Reservation``). Refused at once (``PoolBusy``, ``PoolUnavailable``) when the pool cannot take
        them now, so that a request never waits for part of its work and is then refused for the rest.

        The request holds ``reservation_places(jobs, workers)`` places: no more jobs than the workers can compute
        at once; its other jobs wait for one of its places. A job takes a place without admission and gives it
        back when it ends, so the next job of the request (or a fallback after an infeasible design) reuses it.
        Leaving the block frees every place. A held job was admitted with the jobs ahead of it (the request's own
        included), so it waits for a worker as long as they may take, each within its deadline
        (``turns_ahead``), not the lone job's deadline: a request is refused before its work or answered, not
        refused after part of it."""
        places = reservation_places(jobs, self.workers)
        self._admit(places)
        reservation = _Reservation(self, places)
        self._held += places
        self._changed()
        try:
            yield reservation
        finally:
            try:  # a job cancelled while in a worker still runs there (within its deadline): the request ends after
                await self._settled(reservation.jobs)  # it, so that no work of an answered request is left behind
            finally:
                self._held -= reservation.free
                reservation.free = 0
                reservation.closed = True
                self._changed()

    async def _settled(self, jobs: set[PoolJob]) -> None:
        """Until no worker runs one of ``jobs`` (each ends within its deadline, or its worker is killed)."""
        while jobs and any(worker.job in jobs for worker in self._workers):
            await asyncio.sleep(SETTLE_POLL_S)

    def turns_ahead(self) -> int:
        """Deadlines a job queued now may wait for a worker: one per round of the jobs ahead of it (running or
        queued) over the warm workers, and one more for a worker that is replaced meanwhile."""
        ahead = sum(w.state == "busy" for w in self._workers) + len(self._queue)
        return 1 + math.ceil(ahead / max(1, self._capacity()))

    async def _submit(
        self,
        fn: Callable[..., T],
        args: tuple[Any, ...],
        deadline_s: float,
        wait_s: float | None = None,
        track: set[PoolJob] | None = None,
    ) -> T:
        """Queue an admitted job and wait for its outcome; it waits for a worker at most ``wait_s`` (default: its
        deadline). ``track`` collects the job (a reservation's)."""
        if self._closing or self._loop is None:
            raise PoolUnavailable("the solver pool is not running")
        job = PoolJob(fn, args, deadline_s, self._loop.create_future(), time.monotonic())
        if track is not None:
            track.add(job)
        job.timer = self._loop.call_later(deadline_s if wait_s is None else wait_s, self._expire_queued, job)
        self._queue.append(job)
        self._dispatch()
        try:
            return await job.future  # type: ignore[no-any-return]
        finally:
            if not job.future.done():
                job.future.cancel()
            # The caller went away (its task cancelled, which cancels the future too): a queued job leaves the queue
            # now (it used to stay, counted, until a worker skipped it), a running one finishes.
            if job in self._queue:
                self._queue.remove(job)
                self._cancel_timer(job)
                self._changed()

    def retry_after_s(self, jobs: int = 1) -> int:
        """When room for ``jobs`` is likely to free: the mean solve time times the jobs ahead per worker."""
        ahead = (len(self._queue) + self._held + jobs) / max(1, self.workers)
        return int(min(RETRY_AFTER_MAX_S, max(RETRY_AFTER_MIN_S, math.ceil(self._solve_s_estimate * ahead))))

    def _dispatch(self) -> None:
        try:
            self._dispatch_jobs()
        finally:
            self._changed()

    def _dispatch_jobs(self) -> None:
        assert self._loop is not None
        for worker in self._workers:
            if not self._queue:
                return
            if worker.state != "idle":
                continue
            job = self._queue.popleft()
            self._cancel_timer(job)
            if job.future.done():
                continue
            try:
                worker.conn.send((job.fn, job.args))
            except Exception as exc:  # an argument that cannot be pickled, or a worker that just died
                self._fail(job, exc if not isinstance(exc, OSError) else PoolUnavailable(str(exc)))
                continue
            worker.state, worker.job, worker.started_at = "busy", job, time.monotonic()
            worker.timer = self._loop.call_later(job.deadline_s, self._on_deadline, worker, job)

    def _expire_queued(self, job: PoolJob) -> None:
        if job in self._queue:
            self._queue.remove(job)
            self.rejected += 1
            self._changed()
            waited = time.monotonic() - job.queued_at
            self._fail(
                job,
                PoolBusy(
                    f"no solver worker became free within the solve's deadline ({waited:.3g} s)",
                    retry_after_s=self.retry_after_s(),
                ),
            )

    def _on_deadline(self, worker: PoolWorker, job: PoolJob) -> None:
        if worker.job is job and worker.state == "busy":
            self.timeouts += 1
            self._fail(job, SolveTimeout(job.deadline_s))
            worker.job = None
            self._kill(worker, f"solve overran its deadline of {job.deadline_s:g} s")
