"""Compare: every registered family on one problem, ranked by the load's settling time.

Each family offers its ``candidates`` (its best within the limits, or the caller's override), each
run through the same pipeline as the family's endpoint, so a row's numbers are the endpoint's
answer to the request the row echoes. Of the candidates in one group only the one that settles
first is kept. A family that does not apply, whose limits no design meets, or whose input or solver
fails for this problem, is listed with the reason and its problem type.

A ranking is never shown without a row that the machine's state removed: a family the pool could not
take (``PoolUnavailable``: starting, busy, or its worker died) or whose solve ran out of time
(``SolverTimedOut``, the pool's deadline or the solver's own wall-time cap) makes compare raise that
error, the other runs cancelled (one still queued never runs; one a worker runs ends within its
deadline, and the pool's reservation ends after it). ``plan`` says, before anything runs, how many
runs need a solver, so that the caller can reserve room for all of them at once
(``runtime.executor.reserved``) and be refused before any work. The runner is injected (the pool for
solver families, a thread otherwise), so this module does no I/O.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable, Callable, Coroutine, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from models.errors import DomainError, InvalidParameter, PoolUnavailable, SolverTimedOut
from optim.family import Candidate, Family
from optim.problem import Problem
from optim.registry import FAMILIES
from optim.synthesis import Result

Runner = Callable[[Family, Problem, Any], Awaitable[Result]]
# What the machine's state decides, not the problem: no answer rather than a ranking without the family.
NOT_AN_ANSWER = (PoolUnavailable, SolverTimedOut)


@dataclass(frozen=True)
class ComparedRow:
    family: Family
    options: Any
    result: Result
    label: str = ""

    @property
    def settling_key(self) -> tuple[float, float]:
        """Settling time (never-settling last), then motion time."""
        settle = self.result.metrics.settling.time_s
        return (math.inf if settle is None else settle, self.result.metrics.command_end_s)


@dataclass(frozen=True)
class UnavailableFamily:
    family: str
    reason: str
    problem_type: str  # the slug of the problem type its endpoint answers with (models.errors)


def reason_of(exc: DomainError) -> str:
    """A failure in the user's terms: the field and the rule for invalid input."""
    if isinstance(exc, InvalidParameter):
        return f"{exc.field}: {exc.rule}"
    return str(exc)


async def _one(family: Family, problem: Problem, candidate: Candidate, run: Runner) -> ComparedRow | UnavailableFamily:
    options = candidate.options
    try:
        return ComparedRow(family, options, await run(family, problem, options), candidate.label)
    except NOT_AN_ANSWER:
        raise
    except DomainError as exc:
        return UnavailableFamily(family.name, reason_of(exc), exc.problem_type)


Key = Callable[[ComparedRow], tuple[float, float]]


def _settling(row: ComparedRow) -> tuple[float, float]:
    return row.settling_key


def _best_of_groups(
    candidates: tuple[Candidate, ...], outcomes: list[ComparedRow | UnavailableFamily], key: Key
) -> list[ComparedRow | UnavailableFamily]:
    """Per group, the row first by ``key``; a group with no row gives its first failure."""
    out: list[ComparedRow | UnavailableFamily] = []
    for group in dict.fromkeys(c.group for c in candidates):
        members = [o for c, o in zip(candidates, outcomes, strict=True) if c.group == group]
        rows = [o for o in members if isinstance(o, ComparedRow)]
        out.append(min(rows, key=key) if rows else members[0])
    return out


@dataclass(frozen=True)
class ComparePlan:
    """What compare runs: each applicable family's candidates, and the families that gave none."""

    problem: Problem
    runs: tuple[tuple[Family, tuple[Candidate, ...]], ...]
    unavailable: tuple[UnavailableFamily, ...]

    @property
    def solver_runs(self) -> int:
        """Candidates that run in the solver pool (``Family.uses_solver``), all at once: the room to reserve."""
        return sum(family.uses_solver(c.options) for family, candidates in self.runs for c in candidates)

    @property
    def thread_runs(self) -> int:
        """Candidates that run in the HTTP process's design threads (closed forms), all at once: their room."""
        return sum(not family.uses_solver(c.options) for family, candidates in self.runs for c in candidates)


def plan(
    problem: Problem, names: Iterable[str] | None = None, overrides: Mapping[str, Any] | None = None
) -> ComparePlan:
    """The families that apply and their candidates (the caller's override, or the family's own)."""
    overrides = overrides or {}
    families = [FAMILIES[n] for n in (names or FAMILIES) if n in FAMILIES]
    runs: list[tuple[Family, tuple[Candidate, ...]]] = []
    unavailable: list[UnavailableFamily] = []
    for family in families:
        reason = family.not_applicable(problem)
        if reason is not None:
            unavailable.append(UnavailableFamily(family.name, reason, "not-applicable"))
            continue
        override = overrides.get(family.name)
        try:
            candidates = (Candidate(family.name, override, family.name),) if override else family.candidates(problem)
        except DomainError as exc:  # its default options cannot be built for this problem
            unavailable.append(UnavailableFamily(family.name, reason_of(exc), exc.problem_type))
            continue
        runs.append((family, candidates))
    return ComparePlan(problem, tuple(runs), tuple(unavailable))


async def run_plan(planned: ComparePlan, run: Runner) -> tuple[list[ComparedRow], list[UnavailableFamily]]:
    """Rows sorted by settling time (never-settling designs last), and the families that gave none; the first
    ``NOT_AN_ANSWER`` error (or unexpected error) is raised instead, once the other runs are cancelled."""
    return choose(planned, await run_candidates(planned, run))


async def run_candidates(planned: ComparePlan, run: Runner) -> list[ComparedRow | UnavailableFamily]:
    """Every candidate's outcome, in the plan's order (``run_plan``'s errors)."""
    return await _every_or_first_error([_one(f, planned.problem, c, run) for f, cands in planned.runs for c in cands])


def choose(
    planned: ComparePlan, outcomes: list[ComparedRow | UnavailableFamily], key: Key = _settling
) -> tuple[list[ComparedRow], list[UnavailableFamily]]:
    """Of each group the row first by ``key`` (default: the load's settling, then motion time), the rows sorted by
    it, and the families that gave none."""
    kept: list[ComparedRow | UnavailableFamily] = []
    start = 0
    for _, cands in planned.runs:
        kept += _best_of_groups(cands, outcomes[start : start + len(cands)], key)
        start += len(cands)
    rows = sorted((o for o in kept if isinstance(o, ComparedRow)), key=key)
    failures = [o for o in kept if isinstance(o, UnavailableFamily)]
    # a reason once per family (the shapers share one)
    return rows, list(planned.unavailable) + list(dict.fromkeys(failures))


async def compare(
    problem: Problem, run: Runner, names: Iterable[str] | None = None, overrides: Mapping[str, Any] | None = None
) -> tuple[list[ComparedRow], list[UnavailableFamily]]:
    """``run_plan`` of ``plan``: rows sorted by settling time, and the families that gave none."""
    return await run_plan(plan(problem, names, overrides), run)


async def _every_or_first_error(
    coroutines: list[Coroutine[Any, Any, ComparedRow | UnavailableFamily]],
) -> list[ComparedRow | UnavailableFamily]:
    """Every outcome in order, or the first error: the runs still going are then cancelled (a queued solve leaves
    the queue; one already in a worker ends under its own deadline) and awaited, and the error raised."""
    tasks = [asyncio.ensure_future(c) for c in coroutines]
    if not tasks:
        return []
    try:
        _, pending = await asyncio.wait(tasks, return_when=asyncio.FIRST_EXCEPTION)
    except BaseException:  # this request was cancelled: so are its runs
        for task in tasks:
            task.cancel()
        raise
    errors = [e for t in tasks if t.done() and not t.cancelled() and (e := t.exception()) is not None]
    if not errors:
        return [t.result() for t in tasks]
    for task in pending:
        task.cancel()
    await asyncio.gather(*pending, return_exceptions=True)
    raise errors[0]
