"""Time-outs in compare.

Issue 11, section 4: a solver time-out is never reported as infeasible, in compare either. Issue 23: nor is
it a family left out of the ranking: a ranking never misses a row that the machine's state (a solve out of
time, a worker that died, a full pool) removed; compare answers that error instead (504 solve-timeout, 503).
With a 0.1 ms wall-time cap every IPOPT solve and every time-optimal LP search times out (a time-optimal design
certified before any LP does not: it has no wall-clock check). The wall time is a
last resort that fails the design (issue 23, deterministic designs): STAP's optimized candidate times out too,
rather than fall back to its closed form and give a different design under load.
"""

from __future__ import annotations

import asyncio

import pytest

import vibfree
from app.examples import INCERTI_TABLE_III
from app.schemas.compare import CompareIn
from app.settings import Settings
from models.errors import PoolUnavailable, SolverTimedOut
from optim.compare import compare
from optim.synthesis import synthesize
from runtime.executor import SolveTimeout
from tests import aio
from tests.optim.compare_runner import run_compare

INCERTI_MOVE = {
    "plant": INCERTI_TABLE_III,
    "displacement": 94.24777960769379,
    "limits": {"max_velocity": 200.0, "max_acceleration": 700.0},
}
TINY_CAP = Settings(solve_time_limit_s=1e-4)


def test_time_outs_in_compare_are_time_outs_never_infeasible_nor_a_row_left_out():
    problem = CompareIn.model_validate(INCERTI_MOVE).to_problem(TINY_CAP)
    assert problem.solver.max_wall_time_s == 1e-4
    # Each solver family alone: its time-out is raised as a time-out (SolverTimedOut is no Infeasible).
    for name in ("pseudo_polynomial", "stap"):
        with pytest.raises(SolverTimedOut):
            run_compare(problem, [name])
    # The time-optimal move is certified from its predicted structures before any LP (the wall clock is checked in
    # the LP search only): the same design as without the cap; with a jerk limit too, from a cruise's two dips
    # (structures.two_dip_starts). Where the velocity limit is out of reach (no cruise) its search runs, and times out.
    jerk_limited = {**INCERTI_MOVE, "limits": {**INCERTI_MOVE["limits"], "max_jerk": 20000.0}}
    for move in (INCERTI_MOVE, jerk_limited):
        capped, _ = run_compare(CompareIn.model_validate(move).to_problem(TINY_CAP), ["time_optimal"])
        free, _ = run_compare(CompareIn.model_validate(move).to_problem(Settings()), ["time_optimal"])
        assert capped[0].result.summary.duration_s == free[0].result.summary.duration_s
    no_cruise = {**jerk_limited, "limits": {**jerk_limited["limits"], "max_velocity": 1000.0}}
    with pytest.raises(SolverTimedOut):
        run_compare(CompareIn.model_validate(no_cruise).to_problem(TINY_CAP), ["time_optimal"])
    # A family that needs no solve still gives its rows under the same cap.
    rows, unavailable = run_compare(problem, ["input_shaped"])
    assert rows and not unavailable
    # Every family: the time-out, not a ranking without the time-optimal and pseudo-polynomial rows.
    with pytest.raises(SolverTimedOut):
        run_compare(problem)


def test_the_python_api_compare_answers_the_time_out_as_the_endpoint_does():
    """vibfree.compare runs the route's own answer (InlineExecutor): the 504 problem, not a ranking."""
    with pytest.raises(vibfree.VibfreeError) as error:
        vibfree.compare(INCERTI_MOVE, settings=TINY_CAP)
    assert error.value.status == 504
    assert error.value.problem["type"] == "/problems/solve-timeout"


@pytest.mark.parametrize(
    "error",
    [SolveTimeout(30.0), PoolUnavailable("a solver worker stopped unexpectedly (exit code -9)")],
    ids=["pool-deadline", "worker-died"],
)
def test_one_family_out_of_time_or_without_its_worker_ends_compare_and_cancels_the_rest(error):
    """The error of the failing family is compare's answer at once: the family still running is cancelled, not
    waited for (it would wait for ever here), and no ranking is made without the failing family's row."""
    problem = CompareIn.model_validate(INCERTI_MOVE).to_problem(Settings())
    cancelled: list[str] = []

    async def run(family, p, options):
        if family.name == "pseudo_polynomial":
            await asyncio.sleep(0)
            raise error
        if family.name == "time_optimal":
            try:
                await asyncio.Event().wait()  # never set: only cancellation ends it
            except asyncio.CancelledError:
                cancelled.append(family.name)
                raise
        return synthesize(family, p, options)

    families = ["time_optimal", "pseudo_polynomial", "input_shaped"]
    with pytest.raises(type(error)) as raised:
        aio.run(asyncio.wait_for(compare(problem, run, families), 60))  # 60 s: a guard against a hang, not a bound
    assert raised.value is error
    assert cancelled == ["time_optimal"]
