"""Compare: every registered family on one problem, ranked by the load's settling time.

Each family offers its ``candidates`` (its best within the limits, or the caller's override), each
run through the same pipeline as the family's endpoint, so a row's numbers are the endpoint's
answer to the request the row echoes. Of the candidates in one group only the one that settles
first is kept. A family that does not apply, or whose designs all fail, is listed with the reason
and its problem type. A family the pool could not take (PoolUnavailable: starting or busy) is no part of
an answer: compare raises it, once every run has ended. The runner is injected (the pool for solver
families, a thread otherwise), so this module does no I/O.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable, Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from models.errors import DomainError, Infeasible, InvalidParameter, PoolUnavailable
from optim.family import FAMILIES, Candidate, Family
from optim.problem import Problem
from optim.synthesis import Result

Runner = Callable[[Family, Problem, Any], Awaitable[Result]]


@dataclass(frozen=True)
class Row:
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
class Unavailable:
    family: str
    reason: str
    problem_type: str


def reason_of(exc: DomainError) -> str:
    """A failure in the user's terms: the field and the rule for invalid input."""
    if isinstance(exc, InvalidParameter):
        return f"{exc.field}: {exc.rule}"
    return str(exc)


async def _one(family: Family, problem: Problem, candidate: Candidate, run: Runner) -> Row | Unavailable:
    options = candidate.options
    try:
        try:
            return Row(family, options, await run(family, problem, options), candidate.label)
        except Infeasible:
            fallback = family.fallback(problem, options)
            if fallback is None:
                raise
            return Row(family, fallback, await run(family, problem, fallback), candidate.label)
    except PoolUnavailable:
        raise
    except DomainError as exc:
        return Unavailable(family.name, reason_of(exc), f"/problems/{exc.problem_type}")


def _best_of_groups(candidates: tuple[Candidate, ...], outcomes: list[Row | Unavailable]) -> list[Row | Unavailable]:
    """Per group, the row that settles first; a group with no row gives its first failure."""
    out: list[Row | Unavailable] = []
    for group in dict.fromkeys(c.group for c in candidates):
        members = [o for c, o in zip(candidates, outcomes, strict=True) if c.group == group]
        rows = [o for o in members if isinstance(o, Row)]
        out.append(min(rows, key=lambda r: r.settling_key) if rows else members[0])
    return out


async def compare(
    problem: Problem, run: Runner, names: Iterable[str] | None = None, overrides: Mapping[str, Any] | None = None
) -> tuple[list[Row], list[Unavailable]]:
    """Rows sorted by settling time (never-settling designs last), and the families that gave none."""
    overrides = overrides or {}
    families = [FAMILIES[n] for n in (names or FAMILIES) if n in FAMILIES]
    plans: list[tuple[Family, tuple[Candidate, ...]]] = []
    unavailable: list[Unavailable] = []
    for family in families:
        reason = family.not_applicable(problem)
        if reason is not None:
            unavailable.append(Unavailable(family.name, reason, "/problems/not-applicable"))
            continue
        override = overrides.get(family.name)
        try:
            candidates = (Candidate(family.name, override, family.name),) if override else family.candidates(problem)
        except DomainError as exc:  # its default options cannot be built for this problem
            unavailable.append(Unavailable(family.name, reason_of(exc), f"/problems/{exc.problem_type}"))
            continue
        plans.append((family, candidates))
    runs = await asyncio.gather(
        *(_one(f, problem, c, run) for f, cands in plans for c in cands), return_exceptions=True
    )
    refused = next((o for o in runs if isinstance(o, BaseException)), None)
    if refused is not None:  # a ranking with rows missing because the pool refused them is not an answer
        raise refused
    outcomes = [o for o in runs if not isinstance(o, BaseException)]
    kept: list[Row | Unavailable] = []
    start = 0
    for _, cands in plans:
        kept += _best_of_groups(cands, list(outcomes[start : start + len(cands)]))
        start += len(cands)
    rows = sorted((o for o in kept if isinstance(o, Row)), key=lambda r: r.settling_key)
    failures = [o for o in kept if isinstance(o, Unavailable)]
    return rows, unavailable + list(dict.fromkeys(failures))  # a reason once per family (the shapers share one)
