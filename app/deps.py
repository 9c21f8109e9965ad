"""Named dependencies of the routes."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from app.settings import Settings, get_settings
from optim.workers import SolverPool


async def get_pool(request: Request) -> SolverPool:  # async: FastAPI would run a plain def in a thread
    pool: SolverPool = request.app.state.pool
    return pool


SettingsDep = Annotated[Settings, Depends(get_settings)]
PoolDep = Annotated[SolverPool, Depends(get_pool)]
