"""Batches of designs on worker processes: ``vibfree.synthesize_many(family, requests, processes=N)``.

The moves are cut into chunks of consecutive moves, each designed in a worker process by the serial batch (the
same pipeline, one move after the other), and the answers come back in order: the same answers as one process,
on N cores. The pool is kept for the next batch of the same size (a machine planning cycle after cycle pays the
workers' start once). Workers start from a fork server that has imported the API once ("forkserver"); as with
any multiprocessing, a script that asks for processes runs its calls under ``if __name__ == "__main__":``.

Why not the service's ``runtime.pool.SolverPool``: it supervises long-lived workers for an event loop (deadlines,
admission, restarts), where a batch call from a script needs a pool that maps chunks and gives back results in
order, which ``concurrent.futures.ProcessPoolExecutor`` does.
"""

from __future__ import annotations

import asyncio
import math
import multiprocessing
import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from itertools import repeat
from typing import Any, TypeVar

T = TypeVar("T")
R = TypeVar("R")
CHUNK_MOVES = 16  # moves a job: fewer jobs than moves (each costs a round trip), enough to balance the workers

_POOL: tuple[int, int, ProcessPoolExecutor] | None = None  # (the process that made it, its workers, the pool)
_LOCK = threading.Lock()


def _pool(processes: int) -> ProcessPoolExecutor:
    """The kept pool of ``processes`` workers, made (or remade for another size or in a forked child) on demand."""
    global _POOL
    with _LOCK:
        if _POOL is not None and (_POOL[0] != os.getpid() or _POOL[1] != processes):
            if _POOL[0] == os.getpid():
                _POOL[2].shutdown(wait=False, cancel_futures=True)
            _POOL = None
        if _POOL is None:
            context = multiprocessing.get_context("forkserver")
            context.set_forkserver_preload(["vibfree.api"])  # each worker a fork of a process that imported it
            _POOL = (os.getpid(), processes, ProcessPoolExecutor(processes, mp_context=context))
        return _POOL[2]


def _discard(pool: ProcessPoolExecutor) -> None:
    global _POOL
    with _LOCK:
        if _POOL is not None and _POOL[2] is pool:
            _POOL = None
    pool.shutdown(wait=False, cancel_futures=True)


def chunks(items: Sequence[T], processes: int) -> list[Sequence[T]]:
    """Consecutive runs of at most CHUNK_MOVES items, at least one per process where there are enough."""
    size = max(1, min(CHUNK_MOVES, math.ceil(len(items) / processes)))
    return [items[k : k + size] for k in range(0, len(items), size)]


def in_processes(
    serial: Callable[[str, Sequence[Any], Any], list[T]],
    family: str,
    requests: Sequence[Any],
    settings: Any,
    processes: int,
) -> list[T]:
    """``serial(family, chunk, settings)`` over the chunks of ``requests`` on ``processes`` workers, in order."""
    if not requests:
        return []
    pool = _pool(processes)
    try:
        parts = list(pool.map(serial, repeat(family), chunks(requests, processes), repeat(settings)))
    except BrokenProcessPool as exc:  # a worker died: the next batch gets a new pool
        _discard(pool)
        raise BrokenProcessPool(
            "a batch worker process ended abruptly: killed, out of memory, or the calling script asks for processes "
            'again when a worker imports it (make the call under `if __name__ == "__main__":`)'
        ) from exc
    return [item for part in parts for item in part]


class ProcessesExecutor:
    """A ``runtime.executor.Executor`` on the kept pool of ``processes`` workers: a program's moves designed on every
    core (``vibfree.program(..., processes=N)``). As ``InlineExecutor``, the deadline is not enforced (one caller
    owns the processes; the solvers' own caps bound every solve)."""

    def __init__(self, processes: int) -> None:
        self.workers = processes
        self.pool = _pool(processes)

    async def run(self, fn: Callable[..., R], *args: Any, deadline_s: float) -> R:
        try:
            return await asyncio.wrap_future(self.pool.submit(fn, *args))
        except BrokenProcessPool:
            _discard(self.pool)
            raise
