"""What every CasADi/IPOPT solve shares: its caps, its report and how a failure is told.

A solve is always capped (``max_iter``, ``max_wall_time``). Its report carries IPOPT's status,
iterations and wall time; ``raise_for_status`` turns anything but a converged solve into an
exception, so a failed or capped solve can never be presented as a design.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from models.errors import SolverFailed, SolverTimedOut

# IPOPT return statuses that mean a usable optimum.
CONVERGED = {"Solve_Succeeded", "Solved_To_Acceptable_Level"}
TIMED_OUT = {"Maximum_WallTime_Exceeded", "Maximum_CpuTime_Exceeded"}


@dataclass(frozen=True)
class SolveCaps:
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


def report_of(solver: Any, solve_time_s: float) -> SolverReport:
    """The report of the last call of an nlpsol ``solver`` that took ``solve_time_s``."""
    stats = solver.stats()
    return SolverReport(
        status=str(stats.get("return_status", "unknown")),
        iterations=int(stats.get("iter_count", 0)),
        solve_time_s=float(solve_time_s),
    )


def raise_for_status(report: SolverReport) -> SolverReport:
    if report.timed_out:
        raise SolverTimedOut(report, f"IPOPT reached its wall-time cap after {report.iterations} iterations")
    if not report.converged:
        raise SolverFailed(report)
    return report
