"""Liveness and readiness.

With several HTTP processes (``VIBFREE_PROCESSES``) a probe lands on any one of them, and so does any
request; a process whose solver workers are all cold answers a solve with a 503. So ``/readyz`` is 200
only when every HTTP process of the server has at least one warm worker (and as many processes as
configured are up): a 200 means a request is served wherever it lands. The process that answered says
its pid and its own pool; ``processes`` lists each process's pool as the shared metrics directory has
it (``app.service_metrics.processes_state``). With one process it is that process's pool alone.
"""

from __future__ import annotations

import os
from typing import Any, Literal

from fastapi import APIRouter, Request
from pydantic import Field

from app import problems
from app.deps import PoolDep, SettingsDep
from app.schemas.common import OutModel
from app.service_metrics import processes_state

router = APIRouter(tags=["health"])


class ProcessPool(OutModel):
    pid: int = Field(description="Process id of an HTTP process.")
    ready: int = Field(description="Its warm workers, idle or busy.")
    busy: int = Field(description="Its workers running a solve.")
    starting: int = Field(description="Its workers warming up or waiting to be restarted.")
    queued: int = Field(description="Solves waiting for one of its workers.")


class Threads(OutModel):
    threads: int = Field(description="Design threads configured: closed-form designs and fits computing at once.")
    running: int = Field(description="Design threads computing.")
    queued: int = Field(description="Designs waiting for a design thread.")
    held: int = Field(description="Places reserved for requests' designs not yet submitted (a compare's closed forms).")
    overrunning: int = Field(description="Design threads still computing past their deadline (answered 504).")
    timeouts: int = Field(description="Designs answered 504 at their deadline since start.")
    rejected: int = Field(description="Designs refused since start (queue full, or no thread free within a deadline).")


class Ready(OutModel):
    status: Literal["ready"]
    pid: int = Field(description="Process id of the HTTP process that answered (the counts below are its pool's).")
    workers: int = Field(description="Solver worker processes configured.")
    ready: int = Field(description="Warm workers, idle or busy.")
    busy: int = Field(description="Workers running a solve.")
    starting: int = Field(description="Workers warming up, or waiting to be restarted after a failed warm-up.")
    queued: int = Field(description="Solves waiting for a worker.")
    restarts: int = Field(description="Worker processes replaced since start.")
    timeouts: int = Field(description="Solves killed at their deadline since start.")
    rejected: int = Field(description="Solves refused since start (queue full, or no worker free within a deadline).")
    processes: list[ProcessPool] | None = Field(
        None, description="Every live HTTP process's pool (several processes only); 200 needs each one ready."
    )
    threads: Threads | None = Field(
        None, description="The answering process's design threads (runtime.threads), where closed forms and fits run."
    )


@router.get("/healthz", summary="Liveness: the process answers (never touches a solver)")
async def healthz() -> dict[str, str]:
    return {"status": "ok"}


def _processes(request: Request, expected: int) -> tuple[list[dict[str, int]] | None, str | None]:
    """Each live HTTP process's pool and, if one is not ready or some are missing, why not."""
    directory = request.app.state.metrics.multiprocess_dir
    if directory is None:
        return None, None
    rows = [
        {"pid": pid, **{k: state.get(k, 0) for k in ("ready", "busy", "starting", "queued")}}
        for pid, state in sorted(processes_state(directory).items())
    ]
    cold = [row["pid"] for row in rows if row["ready"] < 1]
    if cold:
        return rows, f"HTTP process(es) {', '.join(map(str, cold))} have no warm solver worker yet"
    if len(rows) < expected:
        return rows, f"{len(rows)} of {expected} HTTP processes are up"
    return rows, None


@router.get(
    "/readyz",
    summary="Readiness: every HTTP process has a warm solver worker",
    response_model=Ready,
    responses=problems.responses(503),
)
async def readyz(request: Request, pool: PoolDep, settings: SettingsDep) -> Any:
    """200 while this process and every other HTTP process of the server have at least one solver worker that
    has built its solvers, with the answering process's pid and pool counts (a dead worker is replaced at
    once, a failed warm-up retried with back-off) and each process's pool under `processes`; else a 503
    problem with the same counts under `pool` and a Retry-After."""
    stats = {"pid": os.getpid(), **pool.stats()}
    if not pool.ready:
        return problems.problem_response("not-ready", "the solver workers are starting or restarting", pool=stats)
    rows, not_ready = _processes(request, settings.processes)
    if not_ready is not None:
        return problems.problem_response("not-ready", not_ready, pool={**stats, "processes": rows})
    lane = getattr(request.app.state, "threads", None)
    return {"status": "ready", **stats, "processes": rows, "threads": None if lane is None else lane.stats()}
