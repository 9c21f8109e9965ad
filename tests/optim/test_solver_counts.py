"""The solver report of a design counts every solver call it made (issue 15: a pseudo-polynomial search of 43
solves reported ``solves: 1``). The calls are counted independently of the families' own bookkeeping: every
IPOPT problem the caches build is wrapped in a counting proxy, and every HiGHS run of the time-optimal LPs
(``highs_model.highs_run``) is counted with its iterations; the design's ``solver.solves`` must equal the calls
and ``iterations`` their sum (exact integers: no tolerance)."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

import optim.families.pseudo_polynomial.problem as pp_problem
import optim.families.stap.problem as stap_problem
import optim.families.time_optimal.highs_model as highs_model
from app.families import BY_NAME
from app.schemas.registry import REQUEST_SCHEMAS
from app.settings import Settings
from optim.registry import FAMILIES
from optim.solver import report_of
from runtime.cache import LruCache


class Calls:
    def __init__(self) -> None:
        self.iterations: list[int] = []


class CountingSolver:
    """An nlpsol that records each call and IPOPT's iteration count of it."""

    def __init__(self, solver: Any, calls: Calls) -> None:
        self.solver, self.calls = solver, calls

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        out = self.solver(*args, **kwargs)
        self.calls.iterations.append(int(self.solver.stats()["iter_count"]))  # IPOPT's count of this call
        return out

    def stats(self) -> Any:
        return self.solver.stats()


@pytest.fixture
def calls(monkeypatch: pytest.MonkeyPatch) -> Calls:
    calls = Calls()
    build_pp, build_stap = pp_problem._build, stap_problem.build_problem

    def pp_build(*args: Any) -> Any:
        c = build_pp(*args)
        return dataclasses.replace(
            c, **{n: CountingSolver(getattr(c, n), calls) for n in ("probe", "quick", "closest", "minimum")}
        )

    def stap_build(*args: Any) -> Any:
        c = build_stap(*args)
        return dataclasses.replace(c, solver=CountingSolver(c.solver, calls))

    # Fresh caches, so that every problem used here is a wrapped one.
    monkeypatch.setattr(pp_problem, "_build", pp_build)
    monkeypatch.setattr(pp_problem, "SOLVER_CACHE", LruCache("test-pp"))
    monkeypatch.setattr(stap_problem, "build_problem", stap_build)
    monkeypatch.setattr(stap_problem, "SOLVER_CACHE", LruCache("test-stap"))

    real_run = highs_model.highs_run

    def highs_run(highs: Any, options: dict[str, Any]) -> tuple[int, int]:
        outcome, iterations = real_run(highs, options)
        calls.iterations.append(iterations)
        return outcome, iterations

    monkeypatch.setattr(highs_model, "highs_run", highs_run)
    return calls


def _example(route: str, name: str) -> tuple[Any, Any, Any]:
    payload = BY_NAME[route].examples[name]["value"]
    body = REQUEST_SCHEMAS[route].model_validate(payload)
    problem = body.to_problem(Settings(workers=1))
    return FAMILIES[route], problem, body.options(problem)


@pytest.mark.parametrize(
    ("route", "name"),
    [
        ("pseudo_polynomial", "incerti_table_iii"),  # one fixed-duration design
        ("pseudo_polynomial", "shortest_with_limits"),  # a duration search: tens of solves
        ("stap", "robust_optimized"),  # multistart
        ("stap", "damped_optimized"),  # multistart on a damped mode
        ("time_optimal", "robust_band"),  # a bisection over LPs with cutting planes (the jerk-limited and known
        # answers are certified with none)
        ("time_optimal", "tradeoff"),  # the design and its trade-off rows
    ],
)
def test_the_report_counts_every_solver_call_and_sums_their_iterations(calls: Calls, route: str, name: str) -> None:
    family, problem, options = _example(route, name)
    design = family.design(problem, options)
    assert design.solver is not None
    assert len(calls.iterations) >= 1
    assert design.solver.solves == len(calls.iterations)
    assert design.solver.iterations == sum(calls.iterations)


def test_a_duration_search_runs_many_solves_and_says_so(calls: Calls) -> None:
    family, problem, options = _example("pseudo_polynomial", "shortest_with_limits")
    design = family.design(problem, options)
    assert design.summary.duration_search  # it searched
    assert design.solver.solves == len(calls.iterations) > 5  # a search is never one solve
    assert design.summary.solver.solves == design.solver.solves  # the response's block says the same


def test_report_of_never_takes_an_iteration_count_ipopt_did_not_record() -> None:
    """A report's iterations are IPOPT's recorded iterations, whatever ``iter_count`` says (issue 15 saw
    186092209 once): a stats dict with a garbage count is read from the per-iteration record instead."""

    class Garbage:
        def stats(self) -> dict[str, Any]:
            return {"return_status": "Solve_Succeeded", "iter_count": 186092209, "iterations": {"obj": [1.0] * 12}}

    class NoRecord:
        def stats(self) -> dict[str, Any]:
            return {"return_status": "Invalid_Number_Detected", "iter_count": -7}

    assert report_of(Garbage(), 0.1).iterations == 11  # 12 recorded points: the start and 11 iterations
    assert report_of(NoRecord(), 0.1).iterations == 0


def test_a_search_that_finds_nothing_counts_its_solves_in_the_design_at_duration_s(calls: Calls) -> None:
    """A duration search that finds nothing falls back to the design at duration_s (with a warning); its report
    counts the search's solves too (before: only the fallback's, e.g. ``solves: 1`` after a search of 43)."""
    family, problem, options = _example("pseudo_polynomial", "shortest_with_limits")
    # A residual tolerance no design meets (round-off is ~1e-16): every probe of the scan fails.
    options = dataclasses.replace(options, residual_tolerance=1e-300)
    design = family.design(problem, options)
    assert any(w.startswith("minimize_duration:") for w in design.warnings)  # the search found none
    assert design.solver.solves == len(calls.iterations) > 5
    assert design.solver.iterations == sum(calls.iterations)


def test_a_failure_leaving_a_design_carries_the_totals_of_its_solves() -> None:
    """``optim.family.counted``: a SolverFailed raised after several solves reports all of them, not the last."""
    from models.errors import SolverFailed
    from optim.family import counted
    from optim.solver import SolverReport, record_solve

    with pytest.raises(SolverFailed) as failure, counted():
        for iterations in (25, 25, 7):
            record_solve(iterations, 0.5)
        raise SolverFailed(SolverReport("Maximum_Iterations_Exceeded", 7, 0.5))
    report = failure.value.report
    assert (report.status, report.solves, report.iterations, report.solve_time_s) == (
        "Maximum_Iterations_Exceeded",
        3,
        57,
        1.5,
    )
