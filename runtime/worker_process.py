"""The solver worker process: what ``runtime.pool.SolverPool`` runs in each process it starts ("spawn").

A worker caps its memory (``limit_memory``), builds its solvers once, when it starts (the families' warm-ups,
``optim.registry.warm_up_all``), keeps them in its module-level caches, says it is ready, then runs jobs sent down
its pipe until told to stop. A job that runs out of memory is answered "too large" (a 422) and the worker serves
on; after each job it gives the freed heap back (``runtime.heap``).
"""

from __future__ import annotations

import contextlib
import os
import resource
import signal
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

from models.errors import InvalidParameter
from runtime.heap import release_free_heap


def limit_memory(memory_mb: int) -> None:
    """Cap this process's address space (RLIMIT_AS) at ``memory_mb`` MiB (0: no cap): an allocation past it raises
    MemoryError here instead of growing the process until the kernel kills one (possibly the HTTP process).
    RLIMIT_AS counts virtual memory: a warm worker maps ~370 MiB more than it has resident (app.settings
    ``worker_memory_mb`` gives the measured figures)."""
    if memory_mb > 0:
        limit = memory_mb * 1024 * 1024
        _, hard = resource.getrlimit(resource.RLIMIT_AS)
        resource.setrlimit(resource.RLIMIT_AS, (limit if hard == resource.RLIM_INFINITY else min(limit, hard), hard))


def _out_of_memory(exc: BaseException) -> bool:
    """A C++ allocation failure surfaced as a Python exception (CasADi's bindings give RuntimeError)."""
    return "std::bad_alloc" in str(exc)


def _too_large(memory_mb: int) -> InvalidParameter:
    """What a job that ran out of memory answers (a 422: the same request would run out again)."""
    where = f"the {memory_mb} MiB a solver worker may use (VIBFREE_WORKER_MEMORY_MB)" if memory_mb else "memory"
    return InvalidParameter(
        "body",
        "too large",
        f"the design needs more than {where}: ask for less work (fewer modes or limits, a lower order, a narrower "
        "band, a longer sample_period_s, a shorter move or horizon)",
    )


def worker_main(conn: Connection, warm_up: Callable[[], None] | None, niceness: int, memory_mb: int = 0) -> None:
    """A worker: cap its memory, warm up, say ready, then run ``(fn, args)`` jobs until told to stop (``None``)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C stops the server, which stops its workers
    limit_memory(memory_mb)  # before the warm-up: a worker that cannot warm up within it fails to start, visibly
    if warm_up is not None:
        warm_up()  # an exception ends the process: the pool sees a failed start and backs off
    if niceness:  # after the warm-up: a replacement warming up niced on a loaded machine took 25-30 s, not ~4 s
        with contextlib.suppress(OSError):
            os.nice(niceness)  # the HTTP process keeps answering while every worker computes
    conn.send(("ready", os.getpid()))
    while True:
        try:
            job = conn.recv()
        except EOFError:
            return
        if job is None:
            return
        fn, args = job
        try:
            outcome: tuple[str, Any] = ("ok", fn(*args))
        except MemoryError:  # past limit_memory: the job's arrays are freed with its frames, the worker serves on
            outcome = ("error", _too_large(memory_mb))
        except Exception as exc:
            # C++ libraries (CasADi, IPOPT) past limit_memory throw std::bad_alloc, raised as a RuntimeError
            outcome = ("error", _too_large(memory_mb) if _out_of_memory(exc) else exc)
        try:
            conn.send(outcome)  # pickled whole before any byte is written
        except Exception as exc:
            conn.send(("error", RuntimeError(f"the solve's {outcome[0]} could not be sent back: {exc!r}")))
        del job, fn, args, outcome
        release_free_heap()  # the job's peak is not kept as the worker's resident set until it is replaced
