"""Liveness and readiness."""

from __future__ import annotations

from fastapi import APIRouter

from app import problems
from app.deps import PoolDep
from app.problems import ProblemError

router = APIRouter(tags=["health"])


@router.get("/healthz", summary="Liveness: the process answers (never touches a solver)")
async def healthz() -> dict[str, str]:
    return {"status": "ok"}


@router.get(
    "/readyz",
    summary="Readiness: the solver workers are up",
    responses=problems.responses(503),
)
async def readyz(pool: PoolDep) -> dict[str, str | int]:
    if not pool.ready:
        raise ProblemError("not-ready", "the solver workers are starting or restarting")
    return {"status": "ready", "workers": pool.workers}
