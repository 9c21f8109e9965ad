"""compare() in-process for the optim tests: every family through the pipeline in this process."""

from __future__ import annotations

import asyncio
from collections.abc import Iterable
from concurrent.futures import ThreadPoolExecutor

from optim.compare import ComparedRow, UnavailableFamily, compare
from optim.problem import Problem
from optim.synthesis import synthesize


async def in_process(family, problem, options):
    return synthesize(family, problem, options)


def run_compare(
    problem: Problem, names: Iterable[str] | None = None
) -> tuple[list[ComparedRow], list[UnavailableFamily]]:
    """compare() on its own event loop in a thread (a browser test may leave one running in this thread)."""
    with ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, compare(problem, in_process, names=names)).result()
