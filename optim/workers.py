"""The solver worker pool.

IPOPT with MUMPS is not thread-safe, so every CasADi solve runs in a worker process, never on the
event loop or in a thread. Each worker builds its solvers once, when it starts (the
families' warm-ups, ``optim.family.warm_up_all``), and
keeps them in its module-level caches. Every call has a deadline: the solve's own cap (IPOPT's
``max_wall_time``) plus a grace period; a worker that overruns it is killed and the pool is
restarted, so one stuck solve cannot hold a worker forever.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from models.errors import PoolUnavailable, SolverTimedOut

log = logging.getLogger(__name__)
T = TypeVar("T")


class SolveTimeout(SolverTimedOut):
    """A solve overran its deadline and its worker was killed."""

    def __init__(self, limit_s: float) -> None:
        self.limit_s = limit_s
        super().__init__(None, f"the solve did not finish within {limit_s:g} s")

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.limit_s,))


def _initialise_worker(warm_up: Callable[[], None] | None) -> None:
    if warm_up is not None:
        warm_up()


def _worker_pid() -> int:
    time.sleep(0.05)  # long enough that concurrent pings land on different workers
    return os.getpid()


class SolverPool:
    """A process pool with readiness, deadlines and restart of stuck workers."""

    def __init__(self, workers: int, start_timeout_s: float = 120.0, warm_up: Callable[[], None] | None = None) -> None:
        self.workers = workers
        self.warm_up = warm_up  # run once in every new worker (a picklable callable: the families' warm-ups)
        self.start_timeout_s = start_timeout_s
        self._executor: ProcessPoolExecutor | None = None
        self._ready = asyncio.Event()
        self._starting: asyncio.Task[None] | None = None

    @property
    def ready(self) -> bool:
        return self._ready.is_set()

    def _new_executor(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_initialise_worker,
            initargs=(self.warm_up,),
        )

    async def start(self) -> None:
        """Start the workers and wait until each has built its solvers."""
        self._executor = self._new_executor()
        await self._warm_up(self._executor)

    def start_in_background(self) -> None:
        """Start without blocking: ``/readyz`` reports when the workers are up."""
        self._executor = self._new_executor()
        self._starting = asyncio.get_running_loop().create_task(self._warm_up(self._executor))

    async def _warm_up(self, executor: ProcessPoolExecutor) -> None:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.start_timeout_s
        pids: set[int] = set()
        try:
            while len(pids) < self.workers and loop.time() < deadline:
                pings = [loop.run_in_executor(executor, _worker_pid) for _ in range(self.workers)]
                pids.update(await asyncio.wait_for(asyncio.gather(*pings), max(0.0, deadline - loop.time())))
        except (TimeoutError, BrokenProcessPool, OSError) as exc:
            log.error("solver workers did not start: %r", exc)
            return
        if executor is self._executor and pids:
            self._ready.set()
            log.info("solver pool ready: %d workers", len(pids))

    async def run(self, fn: Callable[..., T], *args: Any, deadline_s: float) -> T:
        """Run ``fn(*args)`` in a worker; kill and restart the pool if it overruns ``deadline_s``."""
        if not self.ready or self._executor is None:
            raise PoolUnavailable("the solver workers are starting")
        executor = self._executor
        future = asyncio.get_running_loop().run_in_executor(executor, fn, *args)
        try:
            return await asyncio.wait_for(future, deadline_s)
        except TimeoutError:
            self._restart(executor)
            raise SolveTimeout(deadline_s) from None
        except BrokenProcessPool:
            self._restart(executor)
            raise PoolUnavailable("a solver worker stopped unexpectedly; the pool is restarting") from None

    def _restart(self, broken: ProcessPoolExecutor) -> None:
        if broken is not self._executor:
            return  # another call already restarted it
        self._ready.clear()
        _kill(broken)
        self.start_in_background()

    async def close(self) -> None:
        """Stop the workers: let them exit (a second at most), then kill what is left."""
        if self._starting is not None:
            self._starting.cancel()
            await asyncio.gather(self._starting, return_exceptions=True)
        self._ready.clear()
        executor, self._executor = self._executor, None
        if executor is None:
            return
        processes = list((getattr(executor, "_processes", None) or {}).values())
        executor.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            await asyncio.get_running_loop().run_in_executor(None, process.join, 1.0)
            if process.is_alive():
                process.kill()


def _kill(executor: ProcessPoolExecutor) -> None:
    # ProcessPoolExecutor cannot cancel a running call; terminating its processes is the only
    # way to stop a stuck solve. ``_processes`` is private but stable since Python 3.2.
    processes = list((getattr(executor, "_processes", None) or {}).values())
    for process in processes:
        if process.is_alive():
            process.kill()
    executor.shutdown(wait=False, cancel_futures=True)
