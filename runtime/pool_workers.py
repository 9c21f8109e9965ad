"""The solver pool's worker processes: started with a pipe each, watched from the event loop, replaced with back-off."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import multiprocessing
import os
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from typing import Any, Literal

from models.errors import PoolUnavailable
from runtime.worker_process import worker_main

log = logging.getLogger("runtime.pool")  # the pool's logger (docs/deployment.md), in both of its modules

BACKOFF_FIRST_S = 0.5
BACKOFF_MAX_S = 30.0


@dataclass(eq=False)
class PoolJob:
    fn: Callable[..., Any]
    args: tuple[Any, ...]
    deadline_s: float
    future: asyncio.Future[Any]
    queued_at: float
    timer: asyncio.TimerHandle | None = None


@dataclass(eq=False)
class PoolWorker:
    process: BaseProcess
    conn: Connection
    state: Literal["starting", "idle", "busy", "gone"] = "starting"
    job: PoolJob | None = None
    started_at: float = 0.0
    timer: asyncio.TimerHandle | None = None
    killed_for: str = field(default="")


class WorkerSupervisor(ABC):
    """The worker processes of ``runtime.pool.SolverPool``: each is started, watched (its pipe and its sentinel,
    ``loop.add_reader``), killed and replaced on its own; the pool hands them its jobs (``_dispatch``)."""

    def __init__(
        self,
        workers: int,
        start_timeout_s: float,
        warm_up: Callable[[], None] | None,
        niceness: int,
        memory_mb: int,
    ) -> None:
        self.workers = workers
        self.memory_mb = memory_mb  # each worker's address-space cap (limit_memory; 0: none)
        self.warm_up = warm_up  # run once in every new worker (a picklable callable: the families' warm-ups)
        self.start_timeout_s = start_timeout_s
        self.niceness = niceness
        self._context = multiprocessing.get_context("spawn")
        self._loop: asyncio.AbstractEventLoop | None = None
        self._workers: list[PoolWorker] = []
        self._ready_event = asyncio.Event()
        self._closing = False
        self._start_failures = 0
        self._warmed = False  # a worker has been ready once: a later start replaces a worker (see _recovering)
        self._respawns: set[asyncio.TimerHandle] = set()
        self._solve_s_estimate = 1.0  # running mean of solve times, for Retry-After
        self.restarts = 0

    @abstractmethod
    def _dispatch(self) -> None:
        """Hand the queued jobs to the idle workers (after any change of a worker's state)."""

    @abstractmethod
    def _changed(self) -> None:
        """Report the pool's new state (its ``on_change``)."""

    # --- state ---------------------------------------------------------------------------

    @property
    def ready(self) -> bool:
        """At least one worker is warm (idle or busy)."""
        return any(w.state in ("idle", "busy") for w in self._workers)

    @property
    def _recovering(self) -> bool:
        """A worker is starting in place of one that was killed or died, and starts have not been failing: the
        pool takes jobs for it (they queue within their deadlines) instead of refusing them as "starting"."""
        return self._warmed and self._start_failures == 0 and any(w.state == "starting" for w in self._workers)

    def _capacity(self) -> int:
        """Workers a queued job can count on: the warm ones, and the starting ones while ``_recovering``."""
        recovering = self._recovering
        return sum(w.state in ("idle", "busy") or (recovering and w.state == "starting") for w in self._workers)

    def pids(self, state: Literal["starting", "idle", "busy"] | None = None) -> list[int]:
        """Process ids of the live workers, or of those in one state (for tests and operators)."""
        return [
            w.process.pid
            for w in self._workers
            if w.state != "gone" and w.process.pid is not None and (state is None or w.state == state)
        ]

    # --- start --------------------------------------------------------------------------

    def start_in_background(self) -> None:
        """Start every worker without blocking: ``ready`` tells when one is warm."""
        self._loop = asyncio.get_running_loop()
        self._closing = False
        for _ in range(self.workers - len(self._workers)):
            self._spawn()

    async def start(self) -> None:
        """Start the workers and wait until one has built its solvers."""
        self.start_in_background()
        await asyncio.wait_for(self._ready_event.wait(), self.start_timeout_s)

    def _spawn(self) -> None:
        assert self._loop is not None
        parent, child = self._context.Pipe(duplex=True)
        process = self._context.Process(
            target=worker_main,
            args=(child, self.warm_up, self.niceness, self.memory_mb),
            name="vibfree-solver",
            daemon=True,
        )
        process.start()
        child.close()
        worker = PoolWorker(process, parent, started_at=time.monotonic())
        self._workers.append(worker)
        self._loop.add_reader(parent.fileno(), self._on_message, worker)
        self._loop.add_reader(process.sentinel, self._on_exit, worker)
        # uvloop's add_reader makes the fd non-blocking (asyncio's does not): Connection.send/recv of a message
        # larger than the pipe's buffer then fails with BlockingIOError half-way, and the worker was taken for
        # dead (every pseudo-polynomial answer under uvicorn[standard]). The loop only polls it for readiness.
        os.set_blocking(parent.fileno(), True)
        worker.timer = self._loop.call_later(self.start_timeout_s, self._kill, worker, "warm-up timed out")
        self._changed()

    def _respawn_later(self, delay_s: float) -> None:
        assert self._loop is not None

        def respawn() -> None:
            self._respawns.discard(handle)
            if not self._closing:
                self._spawn()

        handle = self._loop.call_later(delay_s, respawn)
        self._respawns.add(handle)
        self._changed()

    # --- worker events -------------------------------------------------------------------

    def _on_message(self, worker: PoolWorker) -> None:
        try:
            os.set_blocking(worker.conn.fileno(), True)  # see _spawn: whatever the loop did to it
            message = worker.conn.recv()
        except (EOFError, OSError):
            self._on_exit(worker)
            return
        except Exception as exc:  # a result that cannot be unpickled here
            message = ("error", RuntimeError(f"the solve's answer could not be read: {exc!r}"))
        kind, payload = message
        if kind == "ready":
            self._cancel_timer(worker)
            worker.state = "idle"
            self._start_failures = 0
            self._warmed = True
            self._ready_event.set()
            log.info("solver worker ready", extra={"pid": payload, "warm_up_s": time.monotonic() - worker.started_at})
        elif worker.job is not None:
            job, worker.job = worker.job, None
            self._cancel_timer(worker)
            worker.state = "idle"
            elapsed = time.monotonic() - worker.started_at
            self._solve_s_estimate += 0.2 * (elapsed - self._solve_s_estimate)
            if kind == "ok":
                if not job.future.done():
                    job.future.set_result(payload)
            else:
                self._fail(job, payload)
        self._dispatch()

    def _on_exit(self, worker: PoolWorker) -> None:
        if worker.state == "gone":
            return
        was = worker.state
        worker.state = "gone"
        self._detach(worker)
        worker.process.join(0.5)  # its sentinel fired: it has exited, this only reaps it
        code = worker.process.exitcode
        with contextlib.suppress(OSError):
            worker.conn.close()
        if worker in self._workers:
            self._workers.remove(worker)
        if worker.job is not None:
            self._fail(
                worker.job,
                PoolUnavailable(f"a solver worker stopped unexpectedly (exit code {code}); it is being replaced"),
            )
            worker.job = None
        if not self.ready:
            self._ready_event.clear()
        if self._closing:
            self._changed()
            return
        self.restarts += 1
        reason = worker.killed_for or f"exit code {code}"
        if was == "starting":
            self._start_failures += 1
            delay = min(BACKOFF_MAX_S, BACKOFF_FIRST_S * 2 ** (self._start_failures - 1))
            log.error("solver worker failed to start; retrying", extra={"reason": reason, "retry_in_s": delay})
            self._respawn_later(delay)
        else:
            log.warning("solver worker replaced", extra={"reason": reason, "state": was})
            self._spawn()
        self._dispatch()

    def _kill(self, worker: PoolWorker, reason: str) -> None:
        if worker.state != "gone" and worker.process.is_alive():
            worker.killed_for = reason
            worker.process.kill()  # its sentinel fires and _on_exit replaces it

    def _detach(self, worker: PoolWorker) -> None:
        self._cancel_timer(worker)
        if self._loop is None:
            return
        with contextlib.suppress(ValueError, OSError):
            self._loop.remove_reader(worker.conn.fileno())
        with contextlib.suppress(ValueError, OSError):
            self._loop.remove_reader(worker.process.sentinel)

    @staticmethod
    def _cancel_timer(item: PoolWorker | PoolJob) -> None:
        if item.timer is not None:
            item.timer.cancel()
            item.timer = None

    @staticmethod
    def _fail(job: PoolJob, exc: BaseException) -> None:
        if not job.future.done():
            job.future.set_exception(exc)
