"""Issue 11, section 4: a solver time-out is never reported as infeasible, in compare either. With a
0.1 ms wall-time cap every IPOPT solve times out; the solver families must say so (or fall back to a
closed form that needs no solve, saying so), never call the move infeasible."""

from __future__ import annotations

from app.examples import INCERTI_TABLE_III
from app.routers.compare import CompareIn
from app.settings import Settings
from tests.optim.compare_runner import run_compare


def test_time_outs_in_compare_are_time_outs():
    settings = Settings(solve_time_limit_s=1e-4)
    body = CompareIn.model_validate(
        {
            "plant": INCERTI_TABLE_III,
            "displacement": 94.24777960769379,
            "limits": {"max_velocity": 200.0, "max_acceleration": 700.0},
        }
    )
    problem = body.to_problem(settings)
    assert problem.solver.max_wall_time_s == 1e-4
    rows, unavailable = run_compare(problem)
    types = {u.family: u.problem_type for u in unavailable}
    assert types.get("pseudo_polynomial") == "/problems/solve-timeout", unavailable
    assert "/problems/infeasible" not in types.values()
    stap = [r for r in rows if r.family.name == "stap"]
    assert stap and all(r.label == "stap/closed_form" or "closed form" in " ".join(r.result.warnings) for r in stap)
