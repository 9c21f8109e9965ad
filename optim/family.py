"""The Family protocol and its base (the registry of families is optim.registry).

A family turns a ``Problem`` and its own options into a ``Design``: the exact command the drive
receives, the family's ``design`` block and its notes. Everything after that (sampling to the
horizon, simulation, metrics, sensitivity, the limit check) is the one pipeline in
``optim.synthesis``, shared by every endpoint and by compare. ``design`` is pure and picklable, so
it can run in a solver worker process.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from models.commands import PiecewiseCommand
from models.errors import SolverFailed
from models.metrics import Metrics
from models.simulation import Response
from optim.problem import Problem
from optim.results import Block, Finish, SensitivityCurve
from optim.solver import SolveCaps, SolverReport, Tally, tally


@dataclass(frozen=True)
class SolverSummary:
    """What the solver did for one design: the last converged solve's status, all solves' iterations and time.

    ``solves`` is every solver call of the design (a duration search, multistarts, re-solves with tightened
    limits, trade-off rows), ``iterations`` their sum: ``counted`` takes both from one tally of the calls
    (``optim.solver.tally``), and gives a failure's report the same totals."""

    status: str
    iterations: int
    solve_time_s: float
    solves: int = 1

    @classmethod
    def of(cls, report: SolverReport, solves: int = 1) -> SolverSummary:
        return cls(report.status, report.iterations, report.solve_time_s, solves)

    @classmethod
    def of_tally(cls, status: str, counts: Tally) -> SolverSummary:
        return cls(status, counts.iterations, counts.seconds, counts.solves)


@contextlib.contextmanager
def counted() -> Iterator[Tally]:
    """Count every solver call of a design; a ``SolverFailed`` leaving the block gets a report with the
    totals (``SolverSummary``: its status, all calls' iterations, time and count), not the last call's."""
    with tally() as counts:
        try:
            yield counts
        except SolverFailed as exc:
            status = str(getattr(exc.report, "status", "unknown"))
            exc.report = SolverSummary.of_tally(status, counts)
            raise


@dataclass(frozen=True)
class Design:
    """A family's design: the exact command (a breakpoint at every kink) and what the family says of it.

    ``command`` is what the drive does, and what the load is simulated with. ``end_s`` is where the
    command stops changing for the horizon rule (default: its last breakpoint). ``detail`` is the
    family's own payload for its sampling and extra blocks (picklable)."""

    command: PiecewiseCommand | None
    summary: Block
    warnings: tuple[str, ...] = ()
    solver: SolverSummary | None = None
    end_s: float | None = None
    detail: Any = None

    @property
    def command_end_s(self) -> float:
        if self.end_s is not None:
            return self.end_s
        if self.command is None:
            raise ValueError("a design without an exact command must give end_s")
        return float(self.command.time_s[-1])


Profile = dict[str, NDArray[np.float64] | None]


@dataclass(frozen=True)
class Grid:
    """The returned series' sampling: period and horizon (s)."""

    period_s: float
    horizon_s: float


@dataclass(frozen=True)
class Run:
    """A sampled command and what the plant does with it."""

    grid: Grid
    command: PiecewiseCommand
    response: Response
    metrics: Metrics


@dataclass(frozen=True)
class Candidate:
    """One design compare runs for a family: a row ``label`` (e.g. ``input_shaped/zvd``) and its
    options. Of the candidates sharing a ``group`` compare keeps the one that settles first, so a
    family can offer alternatives (closed form or optimized, several tuned filters) and show only
    its best, or give each candidate a group of its own to show them all (the shapers)."""

    label: str
    options: Any
    group: str


@runtime_checkable
class Family(Protocol):
    name: ClassVar[str]

    def not_applicable(self, problem: Problem) -> str | None: ...

    def default_options(self, problem: Problem) -> Any: ...

    def design(self, problem: Problem, options: Any) -> Design: ...

    def warm_up(self, solver: SolveCaps) -> None: ...

    def uses_solver(self, options: Any) -> bool: ...

    def sample(self, problem: Problem, design: Design, period_s: float, horizon_s: float) -> PiecewiseCommand: ...

    def profile(self, design: Design, sampled: PiecewiseCommand, grid: Grid) -> Profile | None: ...

    def profile_at(self, design: Design, sampled: PiecewiseCommand, time_s: NDArray[np.float64]) -> Profile: ...

    def finish(self, problem: Problem, design: Design, run: Run) -> Finish: ...

    def sensitivity(
        self, problem: Problem, design: Design, ratios: NDArray[np.float64], zetas: NDArray[np.float64]
    ) -> SensitivityCurve | None: ...

    def candidates(self, problem: Problem) -> tuple[Candidate, ...]: ...


class BaseFamily:
    """Defaults of the hooks a family may override; a family sets ``name`` (app.family_names) and
    implements ``design``."""

    name: ClassVar[str] = ""
    moves_in_motion: ClassVar[bool] = False  # designs moves that start or end in motion (Problem.in_motion)

    def not_applicable(self, problem: Problem) -> str | None:
        return None

    def default_options(self, problem: Problem) -> Any:
        raise NotImplementedError(f"{self.name} must give its default options")

    def warm_up(self, solver: SolveCaps) -> None:
        return None

    def uses_solver(self, options: Any) -> bool:
        return False

    def sample(self, problem: Problem, design: Design, period_s: float, horizon_s: float) -> PiecewiseCommand:
        """The exact command on a uniform grid with its corners kept (the samples describe it exactly)."""
        if design.command is None:
            raise NotImplementedError(f"{self.name} designs no exact command: it must sample itself")
        return design.command.resampled(period_s, end_s=horizon_s)

    def profile(self, design: Design, sampled: PiecewiseCommand, grid: Grid) -> Profile | None:
        """The returned profile when it is not the sampled command itself (default None: it is)."""
        return None

    def profile_at(self, design: Design, sampled: PiecewiseCommand, time_s: NDArray[np.float64]) -> Profile:
        """The returned profile at arbitrary instants (the uniform table of ``optim.tables``): the exact command
        where the design has one, else the sampled one (whose samples hold the instants)."""
        return profile_at_instants(design.command if design.command is not None else sampled, time_s)

    def finish(self, problem: Problem, design: Design, run: Run) -> Finish:
        """The design block completed after sampling, the family's own top-level blocks and warnings (default:
        nothing to add)."""
        return Finish()

    def sensitivity(
        self, problem: Problem, design: Design, ratios: NDArray[np.float64], zetas: NDArray[np.float64]
    ) -> SensitivityCurve | None:
        """The family's own sensitivity curve where it has a closed form (default None: the pipeline's)."""
        return None

    def candidates(self, problem: Problem) -> tuple[Candidate, ...]:
        """What compare runs for this family (default: its ``default_options``, one row)."""
        return (Candidate(self.name, self.default_options(problem), self.name),)


__all__ = [
    "BaseFamily",
    "Candidate",
    "Design",
    "Family",
    "Grid",
    "Profile",
    "Run",
    "SolverSummary",
    "counted",
]


def profile_at_instants(command: PiecewiseCommand, time_s: NDArray[np.float64]) -> Profile:
    """Position to jerk of ``command`` at ``time_s`` (``PiecewiseCommand.evaluate_at_instants``)."""
    values: Profile = {"time_s": time_s}
    rows = command.evaluate_at_instants(time_s, orders=4)
    for m, name in enumerate(("position", "velocity", "acceleration", "jerk")):
        values[name] = rows[m]
    return values
