"""The solver pool under uvloop, the loop uvicorn[standard] runs: uvloop's add_reader makes the pipe to a worker
non-blocking, and an answer larger than the pipe's buffer (64 KiB) was then read half-way and the worker taken
for dead (every pseudo-polynomial answer of a real server was a 503). Both loops must carry a large answer."""

from __future__ import annotations

import pytest

from runtime.pool import SolverPool
from tests import aio
from tests.runtime.pool_jobs import big_answer


async def _round_trip(size: int) -> tuple[int, int]:
    pool = SolverPool(1, 60.0)
    await pool.start()
    try:
        answer = await pool.run(big_answer, size, deadline_s=30.0)
        return len(answer), pool.stats()["restarts"]
    finally:
        await pool.close()


@pytest.mark.parametrize("loop", ["asyncio", "uvloop"])
def test_an_answer_larger_than_the_pipe_buffer_comes_back_whole(loop: str) -> None:
    size = 8 * 1024 * 1024  # 128 pipe buffers
    if loop == "uvloop":
        uvloop = pytest.importorskip("uvloop")
        length, restarts = aio.run(_round_trip(size), runner=uvloop.run)
    else:
        length, restarts = aio.run(_round_trip(size))
    assert (length, restarts) == (size, 0)
