"""Service settings, read from the environment with the ``VIBFREE_`` prefix."""

from __future__ import annotations

import os
from functools import lru_cache

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from optim.solver import SolveCaps


def cores() -> int:
    """The cores this process may run on (its CPU affinity; a container's CPU quota is not seen here)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _default_processes() -> int:
    return cores()


def _default_workers() -> int:
    """Solver workers per HTTP process: 2 (1 on one core), whatever the number of processes.

    Measured on 2 cores (bench/throughput.py, 8 clients): 2 processes x 2 workers served 137 STAP and 53
    pseudo-polynomial req/s, 2 x 1 served 65 and 38: with one worker each, the process the kernel gave more
    connections queues while the other's worker idles; the workers are niced (``worker_niceness``), so the
    extra ones do not starve the HTTP processes. The cost is memory: ~255 MiB per warm worker."""
    return max(1, min(2, cores()))


class Settings(BaseSettings):
    """Limits that keep every request bounded in memory and time."""

    model_config = SettingsConfigDict(env_prefix="VIBFREE_", extra="ignore")

    max_samples: int = Field(200_000, ge=2, description="Most samples in any sampled array, in or out.")
    max_body_bytes: int = Field(32 * 1024 * 1024, ge=1024, description="Largest request body accepted (413 above).")
    identify_max_rows: int = Field(
        600_000,
        ge=2,
        description="Most data rows of a CSV record to identify (Klipper's default resonance test, 130 s, is 416,000 "
        "rows at 3200 Hz and 520,000 at 4000 Hz; its CSV, 19 MB, is within max_body_bytes).",
    )
    solve_time_limit_s: float = Field(
        10.0,
        gt=0,
        description="Wall-clock last resort of each solver call (IPOPT max_wall_time, HiGHS time_limit of an LP): "
        "reached, the design fails with solve-timeout (504). Designs are decided by caps in work, never by time.",
    )
    solve_max_iterations: int = Field(3000, ge=1, description="Iteration cap of one solve (IPOPT max_iter).")
    solve_grace_s: float = Field(5.0, ge=0, description="Extra time before a stuck worker is killed.")
    # --- processes, solver workers and their caches (docs/deployment.md) ---
    processes: int = Field(
        default_factory=_default_processes,
        ge=1,
        le=64,
        description="HTTP server processes (uvicorn --workers), each with its own solver pool; default one per core.",
    )
    workers: int = Field(
        default_factory=_default_workers,
        ge=1,
        le=64,
        description="Solver worker processes of each HTTP process; default 2 (1 on a single core).",
    )
    solver_cache_size: int = Field(
        64, ge=1, le=4096, description="Built solver problems kept per cache in each worker (least recently used go)."
    )
    worker_start_timeout_s: float = Field(120.0, gt=0, description="Time allowed for a worker's warm-up.")
    max_queued: int | None = Field(
        None,
        ge=0,
        le=10_000,
        description="Most solves waiting for a worker in each process (503 beyond); default 4 per server worker.",
    )
    worker_memory_mb: int = Field(
        1536,
        ge=0,
        le=1_048_576,
        description="Address space (RLIMIT_AS, virtual memory) each solver worker may map, in MiB; a job past it is "
        "a 422 and the worker serves on; 0: no limit. Measured (bench/worker_memory.py, single-threaded BLAS as "
        "vibfree serve, the Makefile and the Dockerfile run them): a warm worker mapped 609 MiB for 240 MiB "
        "resident before the time-optimal family's compiled kernels, which map ~400 MiB more (numba and LLVM) for "
        "~100 MiB resident (345-350 MiB warm, at most 438 MiB after 200 distinct plants, within the documented "
        "450 MiB bound); 1536 keeps the ~500 MiB of room above a warm worker that 1024 gave before. OpenBLAS's own "
        "threads add ~100 MiB of mappings each: raise it where BLAS runs threads.",
    )
    worker_niceness: int = Field(
        5, ge=0, le=19, description="Niceness added to the solver workers, so the HTTP process stays responsive."
    )
    threads: int = Field(
        default_factory=cores,
        ge=1,
        le=64,
        description="Design threads of each HTTP process: at most this many closed-form designs and fits compute at "
        "once (runtime.threads); default one per core.",
    )
    max_thread_queued: int | None = Field(
        None,
        ge=0,
        le=10_000,
        description="Most designs waiting for a design thread in each process (503 beyond); default 4 per design "
        "thread of the whole server, at least 16 (a compare asks for 7 closed-form designs at once).",
    )
    thread_deadline_s: float = Field(
        30.0,
        gt=0,
        le=3600,
        description="A design thread's work on one request (504 beyond; the thread finishes in the background), "
        "and the longest a design waits for a thread (503).",
    )
    compare_max_samples: int = Field(
        25_000,
        ge=2,
        description="Most samples in each design of one compare (a row finer than that is unavailable, naming "
        "sample_period_s): its 8 or so rows are held together, so 25000 each keep the answer within one "
        "VIBFREE_MAX_SAMPLES answer (8 rows of 163000 samples held 271 MiB, 620 MiB with include_curves).",
    )
    sweep_max_points: int = Field(
        1000, ge=1, le=100_000, description="Most points of one design sweep, its refinement included (422 above)."
    )
    dask_scheduler: str | None = Field(
        None,
        description="A Dask scheduler (tcp://host:port): design sweeps run their points on that cluster instead of "
        "the solver pool (workers with one thread each: IPOPT is not thread-safe).",
    )

    @property
    def solve_caps(self) -> SolveCaps:
        """The cap of every solve, requests' and warm-ups' alike."""
        return SolveCaps(self.solve_max_iterations, self.solve_time_limit_s)

    @property
    def queue_limit(self) -> int:
        """Solves one process lets wait: by default 4 per solver worker of the whole server (processes x workers),
        since the kernel may hand one process most connections (measured: 2 processes x 1 worker with a limit of
        4 each refused 329 of 8 clients' pseudo-polynomial requests in 6 s; bench/throughput.py)."""
        return 4 * self.workers * self.processes if self.max_queued is None else self.max_queued

    @property
    def thread_queue_limit(self) -> int:
        """Designs one process lets wait for a design thread: by default 4 per design thread of the whole server
        (processes x threads), as ``queue_limit``, and at least 16: a compare alone asks for 7 closed-form designs
        at once (4 shapers, 2 smoothers, STAP's closed form), so two fit on one core."""
        if self.max_thread_queued is not None:
            return self.max_thread_queued
        return max(16, 4 * self.threads * self.processes)

    @property
    def solve_deadline_s(self) -> float:
        """A design's solving time in its worker (several capped solves), and the longest it may wait for one."""
        return 4.0 * self.solve_time_limit_s + self.solve_grace_s


@lru_cache
def get_settings() -> Settings:
    return Settings()
