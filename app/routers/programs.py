"""POST /v1/programs: a machine program (several axes, a cycle of moves, plants that change with position),
designed move by move and checked on the true plant (the use case: app.services.programs)."""

from __future__ import annotations

from collections.abc import AsyncIterator
from typing import Annotated, Literal

import orjson
from fastapi import APIRouter, Body, Query, Request
from fastapi.responses import Response, StreamingResponse

from app import problems
from app.deps import PoolDep, SettingsDep
from app.examples.programs import EXAMPLES
from app.json_bodies import JSONRoute
from app.responses import CSV_MEDIA_TYPE, NumpyJSONResponse, wants_csv
from app.schemas.programs import ProgramIn, ProgramOut
from app.services import programs as use_case
from app.services.sweeps import executor_for
from app.settings import Settings
from optim.programs import Program
from runtime.pool import SolverPool

router = APIRouter(prefix="/v1", tags=["programs"], route_class=JSONRoute)
NDJSON = "application/x-ndjson"


async def _lines(body: ProgramIn, program: Program, settings: Settings, pool: SolverPool) -> AsyncIterator[bytes]:
    """The NDJSON lines, the moves on the pool or on the Dask cluster (``VIBFREE_DASK_SCHEDULER``, connected for
    the stream: closed when it ends or the client goes away)."""
    async with executor_for(settings.dask_scheduler, pool, None) as (executor, capacity):
        async for line in use_case.progress(body, program, settings, executor, capacity):
            yield orjson.dumps(line, option=orjson.OPT_SERIALIZE_NUMPY) + b"\n"


@router.post(
    "/programs",
    summary="A multi-axis cycle of moves, time-optimal and still at every stop, on plants that change with position",
    response_model=ProgramOut,
    responses={
        200: {
            "content": {
                "text/csv": {"schema": {"type": "string"}},
                NDJSON: {"schema": {"type": "string"}},
            },
            "description": "JSON (default); format=csv: the cam table, one column per axis; format=ndjson: a `move` "
            "line per move as it is designed, then the `program` line (the JSON answer), or a `problem` line (the "
            "problem+json) where a move has no design.",
        },
        **problems.responses(413, 422, 503, 504),
    },
)
async def program(
    request: Request,
    body: Annotated[ProgramIn, Body(openapi_examples=EXAMPLES)],
    settings: SettingsDep,
    pool: PoolDep,
    format: Annotated[
        Literal["json", "csv", "ndjson"] | None,
        Query(description="json (default), csv (the cam table) or ndjson (progress lines, then the answer)."),
    ] = None,
) -> Response:
    """Each move is designed by the family (time-optimal by default) from rest at its stop to rest at the next,
    the moves in parallel on the solver pool (or with VIBFREE_DASK_SCHEDULER on that Dask cluster):
    `straight_line` on one path parameter (each axis's limits projected on the direction, every moving axis's
    modes cancelled), `synchronized` (each axis its own design; the faster
    ones averaged with themselves delayed, so that all start and arrive together, within their limits and still
    cancelled) or `independent`. An axis whose plant is a `plant_table` over a coordinate that moves during the
    move is designed for the effective mode that leaves its true, varying plant still (Newton's method on the
    residual of the plant integrated as it changes); where that fails, for the plant at the stop robust over the
    band it passes through, with a warning.

    The answer: the cycle time; per move its design and each axis's metrics and residual at the stop (by the
    cycle's simulation: carried vibration included; on the true plant for a table); per axis the profile and the
    load over the cycle; `comparison`: the same program by Ruckig's synchronized rigid optimum shaped by ZV and
    ZVD at each stop's true modes, and by Klipper's mzv and ei at one frequency per axis, each run through the same
    checks. format=csv: the cam table (time_s and each axis's motor position at t_k = k * period exactly)."""
    if format == "ndjson" or (format is None and NDJSON in request.headers.get("accept", "")):
        program = await use_case.program_of(body, settings, pool)  # a bad program is a 422 before the lines
        return StreamingResponse(_lines(body, program, settings, pool), media_type=NDJSON)
    async with executor_for(settings.dask_scheduler, pool, None) as (executor, capacity):
        answer, result = await use_case.answer(body, settings, executor, capacity)
    if format == "csv" or (format is None and wants_csv(request)):
        return Response(
            use_case.cam_text(result).encode(),
            media_type=CSV_MEDIA_TYPE,
            headers={"content-disposition": 'attachment; filename="program.csv"'},
        )
    return NumpyJSONResponse(answer)
