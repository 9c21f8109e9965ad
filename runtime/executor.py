"""Where a job runs: the ``Executor`` protocol, the in-process executor, and the reservations every executor shares.

An executor runs ``fn(*args)`` within a deadline: the supervised solver pool (``runtime.pool.SolverPool``), the
HTTP process's bounded thread lane (``runtime.threads.ThreadLane``), the calling process (``InlineExecutor``) or a
Dask cluster (``runtime.dask.DaskExecutor``). When it cannot take a job it refuses it at once (``PoolBusy``, a 503
with Retry-After); a job that overruns its deadline is a ``SolveTimeout``.

A request that needs several jobs reserves them all at once (``reserved``): either each gets a place
(a worker or a queue slot) held for it, or none does and the request is refused before any of its
jobs ran. ``HeldPlaces`` is the executor of such a reservation.
"""

from __future__ import annotations

import abc
import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator, Callable, Iterable
from contextlib import AbstractAsyncContextManager, asynccontextmanager
from typing import Any, Protocol, TypeVar, runtime_checkable

from models.errors import PoolUnavailable, SolverTimedOut

T = TypeVar("T")

RETRY_AFTER_MIN_S = 1
RETRY_AFTER_MAX_S = 60


class Executor(Protocol):
    """Where the service layer runs a design: the supervised pool, or in-process (``InlineExecutor``)."""

    async def run(self, fn: Callable[..., T], *args: Any, deadline_s: float) -> T: ...


@runtime_checkable
class Reserving(Executor, Protocol):
    """An executor that can hold room for several jobs of one request at once (the supervised pool)."""

    def reserve(self, jobs: int) -> AbstractAsyncContextManager[Executor]: ...


@asynccontextmanager
async def reserved(executor: Executor, jobs: int) -> AsyncIterator[Executor]:
    """Room for ``jobs`` concurrent jobs of one request, held while the block runs: the executor to run them on.

    On a ``Reserving`` executor (the pool) this is all or nothing: either every job gets a place, or the block
    does not start (``PoolBusy``, ``PoolUnavailable``). Any other executor (``InlineExecutor``, Dask) has no
    admission to ask: the block runs on the executor itself."""
    if jobs < 1 or not isinstance(executor, Reserving):
        yield executor
        return
    async with executor.reserve(jobs) as held:
        yield held


class InlineExecutor:
    """Runs each job in the calling process, one at a time: the Python API and the CLI without a server.

    One caller owns the process, so there is nothing to supervise; the deadline is not enforced (the solvers'
    own caps, ``optim.solver.SolveCaps``, still bound every solve, and Ctrl-C stops the rest)."""

    async def run(self, fn: Callable[..., T], *args: Any, deadline_s: float) -> T:
        return fn(*args)


class SolveTimeout(SolverTimedOut):
    """A solve overran its deadline and its worker was killed."""

    def __init__(self, limit_s: float) -> None:
        self.limit_s = limit_s
        super().__init__(None, f"the solve did not finish within {limit_s:g} s")

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.limit_s,))


class PoolBusy(PoolUnavailable):
    """Every worker is busy and the queue is full, or a job waited its whole deadline for a worker."""

    problem_type = "busy"


def report_change(
    on_change: Callable[[dict[str, int]], None] | None, stats: Callable[[], dict[str, int]], log: logging.Logger
) -> None:
    """Tell ``on_change`` (the metrics' gauges) the executor's new ``stats()``; a failing callback is logged on
    ``log``, never raised: metrics must not break the pool or the lane."""
    if on_change is not None:
        try:
            on_change(stats())
        except Exception:
            log.exception("the on_change callback failed")


def reservation_places(jobs: int, workers: int) -> int:
    """Places a request of ``jobs`` concurrent jobs holds on an executor of ``workers``: no more than can compute
    at once (its other jobs wait for one of its own places, not in the shared queue), and at least one."""
    return max(1, min(jobs, workers))


class HeldPlaces(abc.ABC):
    """The executor of a request's reservation: ``free`` of its places wait for a job of the request; a job beyond
    them waits for one of them (``turn``), so the request never meets admission again. A subclass says how a job
    takes a held place on its executor and gives it back (``_take``, ``_give_back``), and how it runs."""

    def __init__(self, places: int) -> None:
        self.places = places
        self.free = places
        self.turn = asyncio.Semaphore(places)
        self.closed = False  # the request left its block: a job still running gives its place back to nobody

    async def run(self, fn: Callable[..., T], *args: Any, deadline_s: float) -> T:
        if self.closed:  # after the request's block: an ordinary job
            return await self._run_alone(fn, args, deadline_s)
        async with self.turn:
            self._take()
            try:
                return await self._run_held(fn, args, deadline_s)
            finally:
                if not self.closed:  # the place is held again for the request's next job
                    self._give_back()

    @abc.abstractmethod
    def _take(self) -> None: ...

    @abc.abstractmethod
    def _give_back(self) -> None: ...

    @abc.abstractmethod
    async def _run_alone(self, fn: Callable[..., T], args: tuple[Any, ...], deadline_s: float) -> T: ...

    @abc.abstractmethod
    async def _run_held(self, fn: Callable[..., T], args: tuple[Any, ...], deadline_s: float) -> T: ...


async def cancel_all(tasks: Iterable[asyncio.Future[Any]]) -> None:
    """Cancel the tasks still running and wait for each to end (a client that went away: no orphan keeps a worker)."""
    pending = list(tasks)
    for task in pending:
        task.cancel()
    for task in pending:
        with contextlib.suppress(BaseException):
            await task
