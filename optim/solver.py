"""What every CasADi/IPOPT solve shares: its caps, its report and how a failure is told.

A solve is always capped in work (``max_iter``), which decides what a design is, and in wall time
(``max_wall_time``), only as a last resort: a solve that reaches it fails the design with SolverTimedOut,
so that no answer depends on the machine's load. Its report carries IPOPT's status, iterations and
wall time (reported, never decisive); ``raise_for_status`` turns anything but a converged solve into an
exception, so a failed or capped solve can never be presented as a design.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from models.errors import SolverFailed, SolverTimedOut

# IPOPT return statuses that mean a usable optimum.
CONVERGED = {"Solve_Succeeded", "Solved_To_Acceptable_Level"}
TIMED_OUT = {"Maximum_WallTime_Exceeded", "Maximum_CpuTime_Exceeded"}


@dataclass(frozen=True)
class SolveCaps:
    """``max_iterations``: IPOPT's max_iter, a cap in work. ``max_wall_time_s``: each solver call's wall-clock
    last resort (IPOPT's max_wall_time, an LP's HiGHS time_limit): reached, SolverTimedOut."""

    max_iterations: int = 3000
    max_wall_time_s: float = 10.0


@dataclass(frozen=True)
class SolverReport:
    status: str
    iterations: int
    solve_time_s: float

    @property
    def converged(self) -> bool:
        return self.status in CONVERGED

    @property
    def timed_out(self) -> bool:
        return self.status in TIMED_OUT


def parameter_layout(blocks: list[tuple[str, int]]) -> tuple[dict[str, slice], int]:
    """Slices of a flat CasADi parameter vector for named blocks of given sizes, and its length."""
    layout: dict[str, slice] = {}
    start = 0
    for name, size in blocks:
        layout[name] = slice(start, start + size)
        start += size
    return layout, start


def ipopt_options(caps: SolveCaps, **extra: Any) -> dict[str, Any]:
    """nlpsol options: silent, capped in iterations and wall time."""
    options: dict[str, Any] = {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.max_iter": int(caps.max_iterations),
        "ipopt.max_wall_time": float(caps.max_wall_time_s),
    }
    options.update(extra)
    return options


def iterations_of(stats: dict[str, Any]) -> int:
    """IPOPT's iteration count of one call, never a value it did not record.

    ``iter_count`` is the count; IPOPT's per-iteration record (``stats["iterations"]["obj"]``, iteration 0,
    the start, included; a capped solve may record a few restoration steps more) bounds it. A count outside
    [0, recorded] (issue 15 saw 186092209 once) is replaced by the record's own count."""
    try:
        count = int(stats.get("iter_count", 0))
    except (TypeError, ValueError, OverflowError):
        count = -1
    record = stats.get("iterations")
    recorded = len(record["obj"]) - 1 if isinstance(record, dict) and "obj" in record else None
    if recorded is not None and not 0 <= count <= recorded + 1:
        return max(0, recorded)
    return max(0, count)


def report_of(solver: Any, solve_time_s: float) -> SolverReport:
    """The report of the last call of an nlpsol ``solver`` that took ``solve_time_s`` (counted in every
    active ``tally``)."""
    stats = solver.stats()
    report = SolverReport(
        status=str(stats.get("return_status", "unknown")),
        iterations=iterations_of(stats),
        solve_time_s=float(solve_time_s),
    )
    record_solve(report.iterations, report.solve_time_s)
    return report


@dataclass
class Tally:
    """Every solver call made while it is active: calls, summed iterations and seconds."""

    solves: int = 0
    iterations: int = 0
    seconds: float = 0.0


_TALLIES: contextvars.ContextVar[tuple[Tally, ...]] = contextvars.ContextVar("solver_tallies", default=())


def record_solve(iterations: int, seconds: float) -> None:
    """Count one solver call (IPOPT through ``report_of``, an LP of the time-optimal family) in every tally."""
    for tally in _TALLIES.get():
        tally.solves += 1
        tally.iterations += int(iterations)
        tally.seconds += float(seconds)


@contextlib.contextmanager
def tally() -> Iterator[Tally]:
    """Count every solver call made inside the block (nested tallies each count them)."""
    current = Tally()
    token = _TALLIES.set((*_TALLIES.get(), current))
    try:
        yield current
    finally:
        _TALLIES.reset(token)


def raise_for_status(report: SolverReport) -> SolverReport:
    if report.timed_out:
        raise SolverTimedOut(report, f"IPOPT reached its wall-time cap after {report.iterations} iterations")
    if not report.converged:
        raise SolverFailed(report)
    return report
