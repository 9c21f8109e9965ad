"""Named dependencies of the routes."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from app.settings import Settings
from runtime.pool import SolverPool
from runtime.threads import ThreadLane


async def get_app_settings(request: Request) -> Settings:
    """The app's own settings (``create_app``). Not a ``dependency_overrides`` entry: with any override FastAPI
    rebuilds the dependant of every sub-dependency on every request (``solve_dependencies``), a quarter of a
    1k-sample STAP request's time in bench/http_io.py's profile."""
    settings: Settings = request.app.state.settings
    return settings


async def get_pool(request: Request) -> SolverPool:  # async: FastAPI would run a plain def in a thread
    pool: SolverPool = request.app.state.pool
    return pool


async def get_threads(request: Request) -> ThreadLane:
    """The process's design threads (``runtime.threads``): where the closed-form designs and fits run."""
    threads: ThreadLane = request.app.state.threads
    return threads


SettingsDep = Annotated[Settings, Depends(get_app_settings)]
PoolDep = Annotated[SolverPool, Depends(get_pool)]
ThreadsDep = Annotated[ThreadLane, Depends(get_threads)]
