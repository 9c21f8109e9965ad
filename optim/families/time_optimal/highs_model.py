"""The time-optimal search's LPs in HiGHS (highspy), a model kept between solves.

A model is passed to HiGHS once; where the band's dense check adds points (a cutting-plane round of the search),
their columns and rows are added to it and it is solved again from the last basis (HiGHS's dual simplex, warm),
instead of building and solving the larger LP from nothing.

Every LP is capped in work, so that a search is the same on any machine under any load: MAX_LP_ITERATIONS
HiGHS iterations per method (its simplex, then its interior-point method), after which the LP counts as "no
command found" at its length (a capped LP, reported in the design's search block); MAX_LP_SOLVES LPs per search
(SolverFailed beyond). Wall-clock time is only a last resort: HiGHS's own ``time_limit`` (the solve's
max_wall_time_s) reached, the design fails with SolverTimedOut, never a different design.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import highspy
import numpy as np
import scipy.sparse as sp
from highspy._core import _Highs
from numpy.typing import NDArray

from models.errors import InvalidParameter, SolverFailed, SolverTimedOut
from optim.families.time_optimal.sparse_lp import SparseLp, band_rows
from optim.solver import SolverReport, record_solve

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]
# HiGHS iterations per LP and method (HiGHS's simplex_iteration_limit and ipm_iteration_limit).
# The LPs of tests/optim/test_time_optimal.py, the README's examples and bench/determinism.py's 50 random requests
# need at most 4036 simplex iterations (a band down to 1 mHz, 3856 rows; the 1 s time limit used to stop them) and
# 16 interior-point ones; one LP of the stalling move of those tests never ends in the simplex (515 000 iterations in
# 30 s), and the interior-point method proves it infeasible in 16.
MAX_LP_ITERATIONS = 10_000
MAX_LP_SOLVES = 200  # LPs per search (those runs need at most 30): beyond, SolverFailed
# A run's outcome (scipy.optimize.linprog's status codes, and HiGHS's wall-clock last resort).
OPTIMAL, CAPPED, INFEASIBLE, FAILED, TIMED_OUT = 0, 1, 2, 4, -1


@dataclass
class LpCounter:
    """The LPs of one search: HiGHS runs (``solves``), their iterations and seconds, the runs that stopped at
    ``max_iterations`` (``capped_runs``) and the LPs that therefore counted as not found (``capped_lps``).
    ``time_limit_s``: each run's wall-clock last resort (HiGHS's own clock)."""

    time_limit_s: float = math.inf
    max_iterations: int = field(default_factory=lambda: MAX_LP_ITERATIONS)
    max_solves: int = field(default_factory=lambda: MAX_LP_SOLVES)
    solves: int = 0
    iterations: int = 0
    seconds: float = 0.0
    capped_runs: int = 0
    capped_lps: int = 0

    def report(self, status: str) -> SolverReport:
        return SolverReport(status, self.iterations, self.seconds)


def highs_run(highs: Any, options: dict[str, Any]) -> tuple[int, int]:
    """One HiGHS run of ``highs`` with ``options`` set: (outcome, iterations). Outcomes: OPTIMAL, CAPPED (its
    iteration cap), INFEASIBLE (proven), TIMED_OUT (its ``time_limit``: LpModel.solve raises SolverTimedOut), FAILED
    (anything else, e.g. unbounded or infeasible undecided: nothing is proven)."""
    for name, value in options.items():
        highs.setOptionValue(name, value)
    highs.run()
    info = highs.getInfo()
    iterations = max(0, int(info.simplex_iteration_count)) + max(0, int(info.ipm_iteration_count))
    status = highs.getModelStatus()
    outcomes = {
        highspy.HighsModelStatus.kOptimal: OPTIMAL,
        highspy.HighsModelStatus.kIterationLimit: CAPPED,
        highspy.HighsModelStatus.kInfeasible: INFEASIBLE,
        highspy.HighsModelStatus.kTimeLimit: TIMED_OUT,
    }
    return outcomes.get(status, FAILED), iterations


class LpModel:
    """A SparseLp in HiGHS: ``solve`` it, ``add_band`` points, ``solve`` again warm."""

    def __init__(self, lp: SparseLp, counter: LpCounter) -> None:
        self.counter = counter
        self.columns = lp.lower.size
        matrix = sp.vstack(lp.ub + lp.eq).tocsc()  # (the row order of scipy's linprog: inequalities first)
        ub_rhs = np.concatenate(lp.ub_rhs) if lp.ub else np.zeros(0)
        eq_rhs = np.concatenate(lp.eq_rhs) if lp.eq else np.zeros(0)
        require_finite(lp.cost, matrix, ub_rhs, eq_rhs)
        model = highspy.HighsLp()
        model.num_col_, model.num_row_ = self.columns, matrix.shape[0]
        model.col_cost_, model.col_lower_, model.col_upper_ = lp.cost, lp.lower, lp.upper
        model.row_lower_ = np.concatenate([np.full(ub_rhs.size, -np.inf), eq_rhs])
        model.row_upper_ = np.concatenate([ub_rhs, eq_rhs])
        model.a_matrix_.format_ = highspy.MatrixFormat.kColwise
        model.a_matrix_.start_, model.a_matrix_.index_, model.a_matrix_.value_ = (
            matrix.indptr,
            matrix.indices,
            matrix.data,
        )
        self.highs: Any = _Highs()  # highspy.Highs without its Python callbacks (they print a banner on stdout)
        self.highs.setOptionValue("output_flag", False)
        self.highs.passModel(model)
        self.warm = False  # rows were added since the model was passed: a run starts from the last basis

    def basis(self) -> Any:
        """HiGHS's basis after the last run (for ``start_from`` on another model of the same shape)."""
        return self.highs.getBasis()

    def start_from(self, basis: Any) -> None:
        """The next run starts from ``basis`` (another model's of the same shape: its rows and columns alike)."""
        self.highs.setBasis(basis)
        self.warm = True  # (where HiGHS cannot go on from it, the run is repeated from nothing: ``solve``)

    def add_band(self, weights: CArray, bounds: Array) -> None:
        """|weights_p . x| <= bounds_p at more band points (SparseLp.band's inscribed 16-gon), kept warm."""
        count = weights.shape[0]
        first, self.columns = self.columns, self.columns + 2 * count
        eq, polygon, rhs = band_rows(weights, bounds, True, first, self.columns)
        rows = sp.vstack([eq, polygon]).tocsr()
        require_finite(rows, rhs)
        none = np.zeros(2 * count + 1, dtype=np.int32)
        self.highs.addCols(
            2 * count, np.zeros(2 * count), np.full(2 * count, -np.inf), np.full(2 * count, np.inf), 0, none, [], []
        )
        lower = np.concatenate([np.zeros(eq.shape[0]), np.full(rhs.size, -np.inf)])
        upper = np.concatenate([np.zeros(eq.shape[0]), rhs])
        self.highs.addRows(rows.shape[0], lower, upper, rows.nnz, rows.indptr, rows.indices, rows.data)
        self.warm = True

    def solve(self) -> tuple[Array | None, int]:
        """HiGHS's solution (None unless optimal) and its outcome (OPTIMAL, CAPPED, INFEASIBLE or FAILED).

        HiGHS's simplex now and then stalls on one of these small LPs (seen: 316 steps, held jerk): stopped at
        its iteration cap, the LP is solved again with the interior-point method (same cap), then counts as not
        found. Raises SolverFailed past the search's LP cap, SolverTimedOut when HiGHS reaches its time limit."""
        counter = self.counter
        if counter.solves >= counter.max_solves:
            raise SolverFailed(
                counter.report("lp_solve_cap"),
                f"the time-optimal search reached its cap of {counter.max_solves} LP solves (max_lp_solves) without "
                "an answer",
            )
        options: dict[str, Any] = {
            "presolve": "on",
            "simplex_strategy": 1,  # dual
            "simplex_iteration_limit": counter.max_iterations,
            "ipm_iteration_limit": counter.max_iterations,
        }
        if math.isfinite(counter.time_limit_s):
            options["time_limit"] = counter.time_limit_s
        outcome = CAPPED
        for solver in ("choose", "ipm"):
            outcome = self._run({**options, "solver": solver})
            if outcome == FAILED and self.warm:  # HiGHS could not go on from the last basis (seen: kNotset after 0
                self.highs.clearSolver()  # iterations on a band of 3 damping ratios): once more from nothing
                outcome = self._run({**options, "solver": solver})
            if outcome == OPTIMAL:
                return np.asarray(self.highs.getSolution().col_value, dtype=float), OPTIMAL
            if outcome == TIMED_OUT:
                raise SolverTimedOut(
                    counter.report("lp_time_limit"),
                    f"an LP reached its wall-clock last resort ({counter.time_limit_s:g} s, the solve time limit) "
                    f"after {counter.solves} LP solves of the search: no design is returned",
                )
            if outcome != CAPPED:  # proven infeasible, or a numerical failure: no second method
                break
            counter.capped_runs += 1
        if outcome == CAPPED:
            counter.capped_lps += 1
        return None, outcome

    def _run(self, options: dict[str, Any]) -> int:
        """One HiGHS run, counted (solves, iterations, seconds). HiGHS's clock runs on over a kept model's runs, so
        a run's ``time_limit`` is set past the model's run time so far (each LP keeps its own last resort)."""
        if "time_limit" in options:
            options = {**options, "time_limit": self.highs.getRunTime() + options["time_limit"]}
        started = time.perf_counter()
        outcome, iterations = highs_run(self.highs, options)
        seconds = time.perf_counter() - started  # reported only: nothing below depends on it
        self.counter.solves += 1
        self.counter.iterations += iterations
        self.counter.seconds += seconds
        record_solve(iterations, seconds)
        return outcome


def require_finite(*parts: Array | sp.spmatrix | None) -> None:
    """Refuse an LP whose rows are not finite in double precision (InvalidParameter on the body): a move, limits and
    modes whose scales are too far apart (the fuzz bench: a 1e-9 ramp at 5e11 on a 0.001 Hz mode lasts 2e-21 s, a
    band bound of 5e-324 % is 0) give inf / 0 rows, which HiGHS cannot take; no design is claimed impossible."""
    for part in parts:
        if part is None:
            continue
        data = part.data if sp.issparse(part) else part
        if not np.all(np.isfinite(data)):
            raise InvalidParameter(
                "body",
                "not finite",
                "the move, its limits and the plant's modes span scales too far apart for the time-optimal linear "
                "programme in double precision: bring them closer (e.g. a longer move, looser limits, a band nearer "
                "the mode)",
            )
