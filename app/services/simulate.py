"""The simulate use case: the load's response to a sampled motor command given by the caller."""

from __future__ import annotations

from typing import Any

from app.presenters import load_json, metrics_json
from app.schemas.plants import to_plant
from app.schemas.simulate import SimulateRequest, to_command
from app.services.drive import Criteria, closed_loop_block
from models.metrics import metrics
from models.simulation import simulate
from optim.problem import VIBRATION_FRACTION_OF_MOVE
from optim.results import MetricsReport
from optim.synthesis import profile_arrays


def answer(request: SimulateRequest, max_samples: int) -> dict[str, Any]:
    """The plant, started at rest, driven by the command (exactly, for the chosen hold between samples), and the
    metrics of the load's free oscillation from the state at the command's end (JSON-ready apart from arrays)."""
    plant = to_plant(request.plant)
    command, warnings = to_command(request.profile, request, max_samples)
    response = simulate(plant, command)
    tolerance, vibration_window = request.settling_criteria()
    if "settling_tolerance" in request.model_fields_set:
        warnings = [*warnings, "settling_tolerance is deprecated: use settling.position_tolerance"]
    result = metrics(
        response, tolerance, request.settling_window, vibration_window, vibration_fraction=VIBRATION_FRACTION_OF_MOVE
    )
    answer = {
        "profile": profile_arrays(command),
        "load": load_json(response),
        "metrics": metrics_json(MetricsReport(result)),
        "warnings": warnings,
    }
    if request.drive is not None:
        how = Criteria(tolerance, request.settling_window, vibration_window, VIBRATION_FRACTION_OF_MOVE)
        answer["closed_loop"] = closed_loop_block(request.drive, plant, command, response, result, how, max_samples)
    return answer
