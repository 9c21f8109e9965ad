"""Simulation of any sampled motor command on any plant."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Depends
from starlette.responses import Response

from app import problems
from app.deps import SettingsDep, ThreadsDep
from app.examples import SIMULATE_EXAMPLES
from app.json_bodies import JSONRoute
from app.responses import ARRAY_RESPONSE_DOC, ArrayOutput, Output, render
from app.schemas.simulate import SimulateRequest, SimulateResponse
from app.services import simulate as simulation
from app.settings import Settings

router = APIRouter(prefix="/v1", tags=["simulation"], route_class=JSONRoute)


@router.post(
    "/simulate",
    summary="Load response of a plant to a sampled motor command",
    response_model=SimulateResponse,
    responses={**ARRAY_RESPONSE_DOC, **problems.responses(413, 422)},
)
async def simulate_profile(
    request: Annotated[SimulateRequest, Body(openapi_examples=SIMULATE_EXAMPLES)],
    settings: SettingsDep,
    threads: ThreadsDep,
    output: Annotated[Output, Depends(ArrayOutput(SimulateResponse))],
) -> Response:
    """Simulate the plant, started at rest, driven by the command, exactly for the chosen hold
    between samples. The metrics measure the load's free oscillation from the state at the
    command's end (not a sampled peak), so they do not depend on the horizon."""
    # up to VIBFREE_MAX_SAMPLES samples: in the design threads (runtime.threads), not starlette's 40 of a sync route
    return await threads.run(_simulate, request, settings, output, deadline_s=settings.thread_deadline_s)


def _simulate(request: SimulateRequest, settings: Settings, output: Output) -> Response:
    return render(output, simulation.answer(request, settings.max_samples))
