"""Service settings, read from the environment with the ``VIBFREE_`` prefix."""

from __future__ import annotations

import os
from functools import lru_cache

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from optim.solver import SolveCaps


def _default_workers() -> int:
    return max(1, min(2, os.cpu_count() or 1))


class Settings(BaseSettings):
    """Limits that keep every request bounded in memory and time."""

    model_config = SettingsConfigDict(env_prefix="VIBFREE_", extra="ignore")

    max_samples: int = Field(200_000, ge=2, description="Most samples in any sampled array, in or out.")
    max_body_bytes: int = Field(32 * 1024 * 1024, ge=1024, description="Largest request body accepted (413 above).")
    solve_time_limit_s: float = Field(10.0, gt=0, description="Wall-time cap of one solve (IPOPT max_wall_time).")
    solve_max_iterations: int = Field(3000, ge=1, description="Iteration cap of one solve (IPOPT max_iter).")
    solve_grace_s: float = Field(5.0, ge=0, description="Extra time before a stuck worker is killed.")
    workers: int = Field(default_factory=_default_workers, ge=1, le=64, description="Solver worker processes.")
    worker_start_timeout_s: float = Field(120.0, gt=0, description="Time allowed for a worker's warm-up.")
    max_queued: int | None = Field(
        None, ge=0, le=10_000, description="Most solves waiting for a worker (503 beyond); default 4 per worker."
    )
    worker_niceness: int = Field(
        5, ge=0, le=19, description="Niceness added to the solver workers, so the HTTP process stays responsive."
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
        return 4 * self.workers if self.max_queued is None else self.max_queued

    @property
    def solve_deadline_s(self) -> float:
        """A design's solving time in its worker (several capped solves), and the longest it may wait for one."""
        return 4.0 * self.solve_time_limit_s + self.solve_grace_s


@lru_cache
def get_settings() -> Settings:
    return Settings()
