"""POST /v1/compare: every family that applies, on one plant, one move and one set of limits (the use case:
app.services.compare)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples.compare import EXAMPLES
from app.json_bodies import JSONRoute
from app.responses import NumpyJSONResponse
from app.schemas.compare import CompareIn, CompareOut
from app.services.compare import answer

router = APIRouter(prefix="/v1", tags=["compare"], route_class=JSONRoute)


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
