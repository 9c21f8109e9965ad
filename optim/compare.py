"""Compare: every registered family on one problem, ranked by the load's settling time.

Each family runs with its ``default_options`` (its best within the limits) or the caller's override,
through the same pipeline as its endpoint, so a row's numbers are the endpoint's answer to the
request the row echoes. A family that does not apply, or whose design fails, is listed with the
reason and its problem type. The runner is injected (the pool for solver families, a thread
otherwise), so this module does no I/O.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from models.errors import DomainError, Infeasible, InvalidParameter
from optim.family import FAMILIES, Family
from optim.problem import Problem
from optim.synthesis import Result

Runner = Callable[[Family, Problem, Any], Awaitable[Result]]


@dataclass(frozen=True)
class Row:
    family: Family
    options: Any
    result: Result

    @property
    def settling_key(self) -> tuple[bool, float]:
        settle = self.result.metrics.settling.time_s
        return (settle is None, settle or 0.0)


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


async def _one(family: Family, problem: Problem, options: Any, run: Runner) -> Row | Unavailable:
    reason = family.not_applicable(problem)
    if reason is not None:
        return Unavailable(family.name, reason, "/problems/not-applicable")
    try:
        try:
            return Row(family, options, await run(family, problem, options))
        except Infeasible:
            fallback = family.fallback(problem, options)
            if fallback is None:
                raise
            return Row(family, fallback, await run(family, problem, fallback))
    except DomainError as exc:
        return Unavailable(family.name, reason_of(exc), f"/problems/{exc.problem_type}")


async def compare(
    problem: Problem, run: Runner, names: Iterable[str] | None = None, overrides: Mapping[str, Any] | None = None
) -> tuple[list[Row], list[Unavailable]]:
    """Rows sorted by settling time (never-settling designs last) and the families that gave none."""
    overrides = overrides or {}
    families = [FAMILIES[n] for n in (names or FAMILIES) if n in FAMILIES]
    outcomes = await asyncio.gather(
        *(_one(f, problem, overrides.get(f.name) or f.default_options(problem), run) for f in families)
    )
    rows = sorted((o for o in outcomes if isinstance(o, Row)), key=lambda r: r.settling_key)
    return rows, [o for o in outcomes if isinstance(o, Unavailable)]
