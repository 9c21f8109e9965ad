"""POST /v1/sweeps: one family's design at every point of a grid of requests, streamed as NDJSON, and the table
check between neighbouring points (the use case: app.services.sweeps). Points run on the solver pool (closed forms
too, so that they use every worker), at most a worker's job running and one queued per worker, or with
``VIBFREE_DASK_SCHEDULER`` on a Dask cluster.
"""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator
from typing import Annotated

import orjson
from fastapi import APIRouter, Body
from starlette.concurrency import run_in_threadpool
from starlette.responses import JSONResponse, StreamingResponse

from app import problems
from app.deps import PoolDep, SettingsDep
from app.examples.sweeps import EXAMPLES
from app.json_bodies import JSONRoute
from app.schemas.sweeps import SweepIn, SweepLine
from app.services.sweeps import SweepPlan, executor_for, lines
from runtime.executor import Executor

router = APIRouter(prefix="/v1", tags=["sweeps"], route_class=JSONRoute)
NDJSON = "application/x-ndjson"


class NDJSONResponse(StreamingResponse):
    media_type = NDJSON


class _NDJSONLines(JSONResponse):
    """Documentation only: FastAPI then takes the 200 schema from ``responses`` whole (a JSON line's schema) instead
    of ``type: string``; the route answers with an ``NDJSONResponse``."""

    media_type = NDJSON


async def _stream(
    plan: SweepPlan, executor: Executor, capacity: int | None, stack: contextlib.AsyncExitStack
) -> AsyncIterator[bytes]:
    async with stack:  # the Dask client, closed when the stream ends or the client goes away
        async for line in lines(plan, executor, capacity):
            yield orjson.dumps(line, option=orjson.OPT_SERIALIZE_NUMPY) + b"\n"


@router.post(
    "/sweeps",
    summary="One family's design across a grid of requests, and whether the table may be interpolated",
    response_class=_NDJSONLines,
    responses={
        200: {
            "model": SweepLine,
            "description": "NDJSON (application/x-ndjson): one JSON object per line, each with its `line` type: a "
            "`row` per point as it finishes, a `check` per pair of neighbours once both are done, the `summary` "
            "last.",
        },
        **problems.responses(413, 422, 503),
    },
)
async def sweep(
    body: Annotated[SweepIn, Body(openapi_examples=EXAMPLES)], settings: SettingsDep, pool: PoolDep
) -> NDJSONResponse:
    """Runs the family at every point of the axes' Cartesian product (at most VIBFREE_SWEEP_MAX_POINTS points; an
    axis is any numeric field of the base request by its path, as a list of values or a range) and streams one line
    per point as it finishes: duration, settling, percentage vibration, band, solver, or the problem its endpoint
    would answer. Then, for each pair of neighbours along an axis, the table check: the percentage vibration of
    each point's command on the other's plant, passing when both are <= threshold_percent, so that the user knows
    whether designs may be interpolated (or looked up by the nearest point) between them. refine: true bisects the
    failing pairs along their axis, round after round, up to max_refined_points new points.

    Points run on the solver pool (all of them, closed forms too), one running and one queued per worker; a full
    pool delays a point, never fails it. With VIBFREE_DASK_SCHEDULER=tcp://host:port they run on that Dask cluster
    (workers with one thread each). Closing the connection stops the points not yet started."""
    plan = await run_in_threadpool(SweepPlan, body, settings)
    stack = contextlib.AsyncExitStack()  # connected before the answer starts: a failure to connect is a problem
    executor, capacity = await stack.enter_async_context(executor_for(settings.dask_scheduler, pool, None))
    return NDJSONResponse(_stream(plan, executor, capacity, stack))
