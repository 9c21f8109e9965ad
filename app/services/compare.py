"""The compare use case: every family that applies, on one plant, one move and one set of limits.

The families run through the same pipeline as their endpoints (``optim.compare``), each with its best options
within the limits; ``rows[].request`` is the request that reproduces a row when POSTed to ``rows[].endpoint``.
The route (app.routers.compare) and the Python API (vibfree.api) both call ``answer``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import anyio.to_thread

from app.family_names import endpoint_of
from app.presenters import load_json, present
from app.request_bodies import request_fields
from app.schemas.compare import DEFAULT_SENSITIVITY, CompareIn
from app.services import profile as profiles
from app.services.drive import SAMPLE_CAP_FIELD, design_through_drive, reference_residuals, refuse_a_second_drive
from app.settings import Settings
from models.errors import InvalidParameter
from optim.compare import ComparedRow, ComparePlan, UnavailableFamily, choose, plan, reason_of, run_candidates
from optim.family import Family
from optim.problem import Problem
from optim.synthesis import Result
from runtime.executor import Executor, reserved


async def answer(
    body: CompareIn, settings: Settings, pool: Executor, threads: Executor = profiles.INLINE
) -> dict[str, Any]:
    """The compare answer (JSON-ready apart from numpy arrays), run on ``pool`` and ``threads`` (profiles.run): the
    route's and the Python API's."""
    if body.sensitivity is None:
        body = body.model_copy(update={"sensitivity": DEFAULT_SENSITIVITY})
    refuse_a_second_drive(body)
    problem = await anyio.to_thread.run_sync(body.to_problem, settings)
    # every row is held until the last one ends: each gets its share of the sample cap (VIBFREE_COMPARE_MAX_SAMPLES)
    problem = dataclasses.replace(problem, max_samples=min(problem.max_samples, settings.compare_max_samples))
    if not problem.plant.modes():
        raise InvalidParameter("plant", problem.plant.kind, "the plant has no vibration mode to design against")

    planned = plan(problem, body.families, body.options(problem))
    # Room for every design at once, or a 503 busy before any of them ran (no ranking with a row the load removed).
    async with (
        reserved(pool, planned.solver_runs) as solver_executor,
        reserved(threads, planned.thread_runs) as thread_executor,
    ):

        async def run(family: Family, p: Problem, options: Any) -> Result:
            return await profiles.run(family, p, options, settings, solver_executor, thread_executor)

        outcomes = await run_candidates(planned, run)
    common = body.common_body()
    if body.drive is None:
        rows, unavailable = choose(planned, outcomes)
        out = [_row(body, common, row, problem.load_move) for row in rows]
    else:
        out, unavailable = await threads.run(
            _through_drive, body, common, planned, outcomes, deadline_s=settings.thread_deadline_s
        )
    return {
        "move": "rest_to_rest" if problem.rest_to_rest else "rest_to_velocity",
        "rows": out,
        "unavailable": [{**vars(u), "problem_type": f"/problems/{u.problem_type}"} for u in unavailable],
    }


def _through_drive(
    body: CompareIn, common: dict[str, Any], planned: ComparePlan, outcomes: list[ComparedRow | UnavailableFamily]
) -> tuple[list[dict[str, Any]], list[UnavailableFamily]]:
    """Every candidate's command through ``body.drive`` (app.services.drive), each group's design and the rows
    chosen and ranked by the closed loop's settling (never-settling last), then motion time; each row with its
    ``closed_loop`` summary."""
    assert body.drive is not None
    problem = planned.problem
    reference = reference_residuals(body.drive, problem)  # V's, once for every design
    blocks: dict[int, dict[str, Any]] = {}
    for index, row in enumerate(outcomes):  # a loop over the candidates (a few designs)
        if not isinstance(row, ComparedRow):
            continue
        try:
            blocks[id(row)] = design_through_drive(body.drive, problem, row.result, reference)
        except InvalidParameter as exc:  # a design too long for the sampled drive's sample cap: not a row
            if exc.field != SAMPLE_CAP_FIELD:
                raise
            outcomes[index] = UnavailableFamily(row.family.name, reason_of(exc), exc.problem_type)

    def key(row: ComparedRow) -> tuple[float, float]:
        settle = blocks[id(row)]["metrics"]["settling_time_s"]
        return (math.inf if settle is None else settle, row.settling_key[1])

    rows, unavailable = choose(planned, outcomes, key)
    out = []
    for row in rows:  # a loop over the rows
        answer = _row(body, common, row, problem.load_move)
        block = blocks[id(row)]
        metrics = block["metrics"]
        amplitude = metrics["residual_amplitude" if body.displacement is not None else "residual_velocity_amplitude"]
        answer["closed_loop"] = {
            "settling_time_s": metrics["settling_time_s"],
            "residual_amplitude": amplitude,
            "residual_vibration": amplitude / problem.load_move,
            "saturated": block["saturated"],
            "saturation": block["saturation"],
            "simulation": block["simulation"],
        }
        if "curves" in answer:
            answer["curves"]["closed_loop_load"] = block["load"]
        out.append(answer)
    return out, unavailable


def _row(request: CompareIn, common: dict[str, Any], row: ComparedRow, load_move: float) -> dict[str, Any]:
    result: Result = row.result
    family: Family = row.family
    m = result.metrics
    amplitude = m.residual_amplitude if request.displacement is not None else m.residual_velocity_amplitude
    out: dict[str, Any] = {
        "family": family.name,
        "label": row.label or family.name,
        "endpoint": endpoint_of(family.name),
        "request": {**common, **request_fields(family.name, row.options)},
        "motion_time_s": m.command_end_s - float(result.command.time_s[0]),
        "settling_time_s": m.settling.time_s,
        "settling_window": float(m.settling.window),
        "settling_vibration_window": m.settling.vibration_window,
        "percentage_vibration": result.percentage_vibration,
        "residual_vibration": amplitude / load_move,
        "residual_amplitude": amplitude,
        "band_5_percent": present(result.sensitivity.band_5_percent) if result.sensitivity else None,
        "peak_velocity": m.peak_velocity,
        "peak_acceleration": m.peak_acceleration,
        "peak_jerk": m.peak_jerk,
        "peak_motor_torque_nm": m.peak_motor_torque_nm,
        "limits_met": not result.limit_violations,
        "limit_violations": list(result.limit_violations),
        "warnings": [*request.deprecations, *result.warnings],
    }
    if request.include_curves:
        out["curves"] = {
            "profile": result.profile,
            "load": load_json(result.response),
            "sensitivity": present(result.sensitivity),
        }
    return out
