"""The service layer between the routes and the pipeline: where a design runs, and its answer.

A family whose options need a solver runs the whole pipeline in a worker process (IPOPT is not
thread-safe); the others run it in one of the HTTP process's design threads (``runtime.threads.ThreadLane``:
bounded admission and a deadline), off the event loop. Without a server (the Python API, the CLI) both are
the calling process (``InlineExecutor``).
"""

from __future__ import annotations

import time
from typing import Any

import anyio.to_thread

from app.observability import record_solve
from app.presenters import answer_body
from app.schemas.family import ProfileRequest
from app.services.drive import design_through_drive, refuse_a_second_drive
from app.settings import Settings
from models.errors import DomainError, Infeasible, InvalidParameter, NotApplicable
from optim.family import Family
from optim.problem import Problem
from optim.synthesis import Result, synthesize
from runtime.executor import Executor, InlineExecutor

INLINE = InlineExecutor()


async def run(
    family: Family, problem: Problem, options: Any, settings: Settings, pool: Executor, threads: Executor = INLINE
) -> Result:
    """The pipeline's ``Result``: in ``pool`` where the family's options need a solver, else in ``threads``."""
    uses_solver = family.uses_solver(options)
    started = time.perf_counter()
    try:
        if uses_solver:
            result = await pool.run(synthesize, family, problem, options, deadline_s=settings.solve_deadline_s)
        else:
            result = await threads.run(synthesize, family, problem, options, deadline_s=settings.thread_deadline_s)
    except BaseException as exc:  # logged and counted, then raised as before (cancellation included)
        record_solve(family.name, time.perf_counter() - started, error=exc, executor=_executor(uses_solver))
        raise
    record_solve(family.name, time.perf_counter() - started, result=result, executor=_executor(uses_solver))
    return result


def _executor(uses_solver: bool) -> str:
    return "pool" if uses_solver else "thread"


async def profile(
    family: Family, body: ProfileRequest, settings: Settings, pool: Executor, threads: Executor = INLINE
) -> dict[str, Any]:
    """The answer of a family endpoint: the pipeline's result, with a line per deprecated field used."""
    answer, _ = await design(family, body, settings, pool, threads)
    return answer


async def design(
    family: Family, body: ProfileRequest, settings: Settings, pool: Executor, threads: Executor = INLINE
) -> tuple[dict[str, Any], Result]:
    """The answer of a family endpoint and the pipeline's ``Result`` it was made from (for the CSV table)."""
    refuse_a_second_drive(body)
    try:
        problem = await _problem_of(body, settings, pool)
        reason = family.not_applicable(problem)
        if reason is not None:  # before the options, whose defaults may need what is missing (a mode)
            raise NotApplicable(reason)
        result = await run(family, problem, body.options(problem), settings, pool, threads)
    except (InvalidParameter, Infeasible, NotApplicable) as exc:
        raise as_sent(exc, body) from None
    answer = answer_body(result)
    answer["warnings"] = [*body.deprecations, *answer["warnings"]]
    if body.drive is not None:
        answer["closed_loop"] = await threads.run(
            _through_drive, body, problem, result, deadline_s=settings.thread_deadline_s
        )
    return answer, result


def _through_drive(body: ProfileRequest, problem: Problem, result: Result) -> dict[str, Any]:
    """The design's command through ``body.drive`` (app.services.drive), measured with the problem's criteria."""
    assert body.drive is not None
    return design_through_drive(body.drive, problem, result)


async def _problem_of(body: ProfileRequest, settings: Settings, pool: Executor) -> Problem:
    """The request's ``Problem``: in a server off the event loop (a plant's modal form can take milliseconds);
    where the design runs in the calling process (``InlineExecutor``: the Python API, the CLI, whose loop runs this
    design and nothing else) here, without the thread hop (0.4 ms, a tenth of a nominal design)."""
    if isinstance(pool, InlineExecutor):
        return body.to_problem(settings)
    return await anyio.to_thread.run_sync(body.to_problem, settings)


def as_sent(exc: DomainError, body: ProfileRequest) -> DomainError:
    """The error naming the field as the caller sent it (a deprecated alias where one was used)."""
    field = body.caller_field(exc.field)
    if field == exc.field:
        return exc
    if isinstance(exc, InvalidParameter):
        return InvalidParameter(field or "", exc.value, exc.rule)
    if isinstance(exc, Infeasible | NotApplicable):
        return type(exc)(exc.reason, field)
    return exc
