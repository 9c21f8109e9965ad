"""Plant analysis: modes and transfer functions of a plant."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body

from app import problems
from app.examples import PLANT_EXAMPLES
from app.json_bodies import JSONRoute
from app.schemas.common import StrictModel
from app.schemas.plants import PlantAnalysis, PlantIn, analyse, to_plant

router = APIRouter(prefix="/v1/plants", tags=["plants"], route_class=JSONRoute)


class AnalyzeRequest(StrictModel):
    plant: PlantIn


@router.post(
    "/analyze",
    summary="Vibration modes and transfer functions of a plant",
    response_model=PlantAnalysis,
    responses=problems.responses(413, 422),
)
def analyze(request: Annotated[AnalyzeRequest, Body(openapi_examples=PLANT_EXAMPLES)]) -> PlantAnalysis:
    """Validate a plant and derive its modes (natural and damped frequency, damping ratio, period),
    its transfer function to the load and a state-space realisation."""
    return analyse(to_plant(request.plant))
