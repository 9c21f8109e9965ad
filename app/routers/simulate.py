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
from app.schemas.plants import to_plant
from app.schemas.simulate import SimulateRequest, SimulateResponse, load_out, metrics_out, profile_out, to_command
from app.settings import Settings
from models.metrics import metrics
from models.simulation import simulate
from optim.problem import VIBRATION_FRACTION_OF_MOVE

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
    plant = to_plant(request.plant)
    command, warnings = to_command(request.profile, request, settings.max_samples)
    response = simulate(plant, command)
    tolerance, vibration_window = request.settling_criteria()
    if "settling_tolerance" in request.model_fields_set:
        warnings = [*warnings, "settling_tolerance is deprecated: use settling.position_tolerance"]
    result = metrics(
        response, tolerance, request.settling_window, vibration_window, vibration_fraction=VIBRATION_FRACTION_OF_MOVE
    )
    answer = {
        "profile": profile_out(command),
        "load": load_out(response),
        "metrics": metrics_out(result),
        "warnings": warnings,
    }
    return render(output, answer)
