"""POST /v1/compare: every family that applies, on one plant, one move and one set of limits.

The families run through the same pipeline as their endpoints (``optim.compare``), each with its
best options within the limits; ``rows[].request`` is the request that reproduces a row when
POSTed to ``rows[].endpoint``.
"""

from __future__ import annotations

import dataclasses
from typing import Annotated, Any, ClassVar, Literal

from fastapi import APIRouter, Body
from pydantic import Field
from starlette.concurrency import run_in_threadpool

from app import problems, services
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples import CUSIMANO_8HZ, INCERTI_TABLE_III
from app.responses import NumpyJSONResponse
from app.schemas.common import OutModel
from app.schemas.family import ProfileRequest, SensitivityIn, SensitivityOut
from app.schemas.simulate import LoadOut, ProfileOut
from app.schemas.stap import StapSensitivityOut
from app.settings import Settings
from models.errors import InvalidParameter
from optim.compare import Row as ComparedRow
from optim.compare import plan, run_plan
from optim.families.pseudo_polynomial import PseudoPolynomialOptions
from optim.family import Family
from optim.problem import Problem
from optim.synthesis import Result, load_arrays
from optim.workers import Executor, reserved

router = APIRouter(prefix="/v1", tags=["compare"], route_class=problems.JSONRoute)
FamilyName = Literal["time_optimal", "pseudo_polynomial", "stap", "smoother", "input_shaped"]
DEFAULT_SENSITIVITY = SensitivityIn(min_ratio=0.5, max_ratio=1.5, count=201)


class CompareIn(ProfileRequest):
    """One plant, one move (displacement for rest-to-rest, or target_velocity) and one set of limits, with the
    sampling, settling band and sensitivity grid every family is run with (sensitivity default: 0.5..1.5, 201
    ratios, for the 5 % band)."""

    duration_s: float | None = Field(
        None,
        ge=1e-6,
        le=1e5,
        description="Duration of the pseudo-polynomial move (default: the shortest within the limits).",
    )
    families: list[FamilyName] | None = Field(None, min_length=1, description="Run only these families (default: all).")
    include_curves: bool = Field(False, description="Add each design's profile, load response and sensitivity curve.")

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = ("plant: at least one vibration mode to design against.",)

    def options(self, problem: Problem) -> dict[str, Any]:
        if self.duration_s is None:
            return {}
        return {"pseudo_polynomial": PseudoPolynomialOptions(duration_s=self.duration_s)}


class Curves(OutModel):
    profile: ProfileOut
    load: LoadOut
    # a STAP row's sensitivity also says which method computed each curve
    sensitivity: SensitivityOut | StapSensitivityOut | None


class Row(OutModel):
    family: FamilyName
    label: str = Field(description="The design: the family, and the variant where it offers several (input_shaped/zv).")
    endpoint: str = Field(description="The family endpoint; POST `request` there to get this design.")
    request: dict[str, Any] = Field(description="The request that reproduces this row at `endpoint`.")
    motion_time_s: float = Field(description="Until the command's last change.")
    settling_time_s: float | None = Field(
        description="From the start, the earliest time after which the load stays within settling.position_tolerance "
        "and its vibration envelope below settling.vibration_tolerance for ever; null if never."
    )
    settling_window: float = Field(description="The position band settling needs, load units.")
    settling_vibration_window: float | None = Field(
        description="The bound on the load's vibration envelope settling needs, load units."
    )
    percentage_vibration: float | None = Field(
        description="V at the nominal mode, %: the residual over the unshaped rigid command's (see /v1/profiles/*)."
    )
    residual_vibration: float = Field(
        description="Residual left by every mode of the plant (their envelopes summed), fraction of the load's move."
    )
    residual_amplitude: float = Field(
        description="Load free-oscillation envelope (position; velocity for rest-to-velocity)."
    )
    band_5_percent: list[float | None] | None = Field(
        description="f_n/f_n,e range around 1 where the percentage vibration V stays <= 5 % (evaluated on 0.5..1.5; "
        "an end is null where the band runs past that range)."
    )
    peak_velocity: float | None
    peak_acceleration: float | None
    peak_jerk: float | None
    peak_motor_torque_nm: float | None
    limits_met: bool
    limit_violations: list[str]
    warnings: list[str]
    curves: Curves | None = None


class Unavailable(OutModel):
    family: FamilyName
    reason: str
    problem_type: str | None = Field(None, description="The problem type the family's endpoint answers with.")


class CompareOut(OutModel):
    move: Literal["rest_to_rest", "rest_to_velocity"]
    rows: list[Row] = Field(
        description="Sorted by settling time (never-settling designs last), then motion time. A family offering "
        "several variants (shapers) has a row per variant; of alternatives (closed form or optimized, filter kinds) "
        "only the one that settles first."
    )
    unavailable: list[Unavailable]


def _row(request: CompareIn, common: dict[str, Any], row: ComparedRow, load_move: float) -> dict[str, Any]:
    result: Result = row.result
    family: Family = row.family
    m = result.metrics
    amplitude = m.residual_amplitude if request.displacement is not None else m.residual_velocity_amplitude
    out: dict[str, Any] = {
        "family": family.name,
        "label": row.label or family.name,
        "endpoint": family.endpoint,
        "request": {**common, **family.request_fields(row.options)},
        "motion_time_s": m.command_end_s - float(result.command.time_s[0]),
        "settling_time_s": m.settling.time_s,
        "settling_window": float(m.settling.window),
        "settling_vibration_window": m.settling.vibration_window,
        "percentage_vibration": result.percentage_vibration,
        "residual_vibration": amplitude / load_move,
        "residual_amplitude": amplitude,
        "band_5_percent": result.sensitivity["band_5_percent"] if result.sensitivity else None,
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
            "load": load_arrays(result.response),
            "sensitivity": result.sensitivity,
        }
    return out


EXAMPLES: dict[str, dict[str, Any]] = {
    "incerti_rest_to_rest": {
        "summary": "Incerti Table III platform: 15 motor revolutions within velocity and acceleration limits",
        "value": {
            "plant": INCERTI_TABLE_III,
            "displacement": 94.24777960769379,
            "limits": {"max_velocity": 200.0, "max_acceleration": 700.0},
        },
    },
    "cusimano_rest_to_velocity": {
        "summary": "Cusimano 8 Hz two-inertia plant: up to 150 rad/s within the 10 N m motor",
        "value": {"plant": CUSIMANO_8HZ, "target_velocity": 150.0, "limits": {"max_torque_nm": 10.0}},
    },
}


@router.post(
    "/compare",
    summary="Every family side by side on one plant, move and limits",
    response_model=CompareOut,
    responses=problems.responses(413, 422, 503, 504),
)
async def compare(
    body: Annotated[CompareIn, Body(openapi_examples=EXAMPLES)],
    settings: SettingsDep,
    pool: PoolDep,
    threads: ThreadsDep,
) -> NumpyJSONResponse:
    """Runs every family that applies (pseudo-polynomial and smoothers need a rest-to-rest move, STAP an
    acceleration or torque limit) with the same limits, sampling, settling band and sensitivity grid, and returns
    one row per design sorted by the load's settling time. A family that does not apply or cannot meet the limits
    is listed in `unavailable` with its reason. `rows[].request` is the exact request to POST to
    `rows[].endpoint` to get the same design (add `?format=csv` for a cam table).

    A ranking never misses a family for the service's own reasons: the request asks for room for all its designs
    at once (solver workers for its solves, design threads for its closed forms) and is refused at once (503
    `busy`, with Retry-After) when there is not room for every one; a design that runs out of time makes the
    answer a 504 `solve-timeout`, and a solver worker that dies a 503 `not-ready`, rather than a ranking without
    that family."""
    return NumpyJSONResponse(await answer(body, settings, pool, threads))


async def answer(
    body: CompareIn, settings: Settings, pool: Executor, threads: Executor = services.INLINE
) -> dict[str, Any]:
    """The compare answer (JSON-ready apart from numpy arrays), run on ``pool`` and ``threads`` (services.run): the
    route's and the Python API's."""
    if body.sensitivity is None:
        body = body.model_copy(update={"sensitivity": DEFAULT_SENSITIVITY})
    problem = await run_in_threadpool(body.to_problem, settings)
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
            return await services.run(family, p, options, settings, solver_executor, thread_executor)

        rows, unavailable = await run_plan(planned, run)
    common = body.common_body()
    return {
        "move": "rest_to_rest" if problem.rest_to_rest else "rest_to_velocity",
        "rows": [_row(body, common, row, problem.load_move) for row in rows],
        "unavailable": [vars(u) for u in unavailable],
    }
