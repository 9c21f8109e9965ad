"""Liveness and readiness."""

from __future__ import annotations

from typing import Any, Literal

from fastapi import APIRouter
from pydantic import Field

from app import problems
from app.deps import PoolDep
from app.schemas.common import OutModel

router = APIRouter(tags=["health"])


class Ready(OutModel):
    status: Literal["ready"]
    workers: int = Field(description="Solver worker processes configured.")
    ready: int = Field(description="Warm workers, idle or busy.")
    busy: int = Field(description="Workers running a solve.")
    starting: int = Field(description="Workers warming up, or waiting to be restarted after a failed warm-up.")
    queued: int = Field(description="Solves waiting for a worker.")
    restarts: int = Field(description="Worker processes replaced since start.")
    timeouts: int = Field(description="Solves killed at their deadline since start.")
    rejected: int = Field(description="Solves refused since start (queue full, or no worker free within a deadline).")


@router.get("/healthz", summary="Liveness: the process answers (never touches a solver)")
async def healthz() -> dict[str, str]:
    return {"status": "ok"}


@router.get(
    "/readyz",
    summary="Readiness: at least one solver worker is warm",
    response_model=Ready,
    responses=problems.responses(503),
)
async def readyz(pool: PoolDep) -> Any:
    """200 while at least one solver worker has built its solvers, with the pool's counts (a dead worker is
    replaced at once, a failed warm-up retried with back-off); else a 503 problem with the same counts under
    `pool` and a Retry-After."""
    stats = pool.stats()
    if not pool.ready:
        return problems.problem_response("not-ready", "the solver workers are starting or restarting", pool=stats)
    return {"status": "ready", **stats}
