"""POST /v1/profiles/pseudo-polynomial: Incerti's commands with exponents chosen by IPOPT."""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Body, Depends, Request, Response
from starlette.concurrency import run_in_threadpool

from app import problems
from app.examples import CUSIMANO_8HZ, INCERTI_TABLE_III
from app.responses import CSV_RESPONSE_DOC, CsvFormat, negotiate
from app.schemas.family import family_response, sample_count_check
from app.schemas.plants import to_plant
from app.schemas.pseudo_polynomial import SELECTION_RULE, PseudoPolynomialIn, PseudoPolynomialOut
from app.settings import Settings, get_settings
from models.errors import InvalidParameter
from models.plants import Plant
from optim import pseudo_polynomial as synthesis
from optim.solver import SolveCaps
from optim.workers import WARMUPS, SolverPool

router = APIRouter(prefix="/v1", tags=["pseudo-polynomial"])
WARMUPS.append(synthesis.warm_up)

EXAMPLES: dict[str, dict[str, Any]] = {
    "incerti_table_iii": {
        "summary": "Incerti Sec. V: 15 motor revolutions in 1 s on the Table III platform",
        "description": "Starts from the quintic (3, 4, 5), which leaves about 3.5e-3 rad of platform vibration.",
        "value": {"plant": INCERTI_TABLE_III, "displacement": 94.24777960769379, "duration_s": 1.0},
    },
    "incerti_order_4": {
        "summary": "The same move with order 4 (derivatives up to the 4th null at both ends)",
        "value": {"plant": INCERTI_TABLE_III, "displacement": 94.24777960769379, "duration_s": 1.0, "order": 4},
    },
    "shortest_with_limits": {
        "summary": "Shortest move within acceleration and jerk limits (8 Hz two-inertia plant)",
        "value": {
            "plant": CUSIMANO_8HZ,
            "displacement": 10.0,
            "duration_s": 0.8,
            "limits": {"max_acceleration": 200.0, "max_jerk": 5000.0},
            "minimize_duration": True,
        },
    },
}


def core_request(request: PseudoPolynomialIn, plant: Plant, settings: Settings) -> synthesis.PseudoPolynomialRequest:
    if request.displacement == 0.0 or abs(request.displacement) > 1e9:
        raise InvalidParameter("displacement", request.displacement, "must be non-zero and within +-1e9")
    limits = request.limits
    return synthesis.PseudoPolynomialRequest(
        plant=plant,
        displacement=request.displacement,
        duration_s=request.duration_s,
        order=request.order,
        initial_exponents=tuple(request.initial_exponents) if request.initial_exponents else None,
        limits=synthesis.Limits(limits.max_velocity, limits.max_acceleration, limits.max_jerk, limits.max_torque_nm),
        minimize_duration=request.minimize_duration,
        residual_tolerance=request.residual_tolerance,
        caps=SolveCaps(settings.solve_max_iterations, settings.solve_time_limit_s),
    )


def _horizon(request: PseudoPolynomialIn, plant: Plant, duration_s: float) -> float:
    if request.horizon_s is None:
        return duration_s + 5.0 * plant.modes()[0].natural_period_s
    if request.horizon_s < duration_s:
        raise InvalidParameter("horizon_s", request.horizon_s, f"must be >= the duration ({duration_s:.6g} s)")
    return request.horizon_s


def _design_out(design: synthesis.PseudoPolynomialDesign, request: PseudoPolynomialIn) -> dict[str, Any]:
    law, initial = design.law, design.initial
    return {
        "order": law.order,
        "duration_s": law.duration_s,
        "displacement": law.displacement,
        "exponents": list(law.exponents),
        "coefficients": list(law.coefficients),
        "initial_exponents": list(initial.exponents),
        "initial_coefficients": list(initial.coefficients),
        "final_energy_before": design.initial_energy,
        "final_energy_after": design.final_energy,
        "energy_ratio": design.energy_ratio,
        "energy_units": "J" if design.energy_is_physical else "per unit load inertia",
        "residual_amplitude": design.residual_amplitude,
        "initial_residual_amplitude": design.initial_residual_amplitude,
        "selection": design.selection,
        "selection_rule": SELECTION_RULE,
        "bounds": {
            "min_exponent": synthesis.lower_bound(law.order),
            "max_exponent": synthesis.MAX_EXPONENT,
            "min_separation": synthesis.MIN_SEPARATION,
        },
        "solver": {
            "status": design.solver.status,
            "iterations": design.solver.iterations,
            "solve_time_s": design.solver.solve_time_s,
            "solves": design.solves,
        },
        "duration_search": [{"duration_s": d, "feasible": ok} for d, ok in design.duration_search] or None,
    }


def compose(
    request: PseudoPolynomialIn, plant: Plant, design: synthesis.PseudoPolynomialDesign, settings: Settings
) -> dict[str, Any]:
    """The response body for a finished design: samples, simulation, metrics (CPU work)."""
    law = design.law
    horizon = _horizon(request, plant, law.duration_s)
    sample_count_check(horizon, request.sample_period_s, settings.max_samples)
    try:
        command = law.command(request.sample_period_s, horizon)
    except InvalidParameter as exc:  # a sample beyond 1e12: the move itself is out of range
        raise InvalidParameter("duration_s", law.duration_s, f"the move is too fast to sample ({exc.rule})") from None
    body, _result = family_response(
        plant,
        command,
        _design_out(design, request),
        sensitivity_request=request.sensitivity,
        settling_tolerance=request.settling_tolerance,
    )
    body["profile"] = law.samples(command.time_s)  # the law's exact values, for the drive
    initial_command = design.initial.command(
        request.sample_period_s, _horizon(request, plant, design.initial.duration_s)
    )
    initial_body, _ = family_response(plant, initial_command, {}, settling_tolerance=request.settling_tolerance)
    body["initial"] = {
        "profile": design.initial.samples(initial_command.time_s),
        "load": initial_body["load"],
        "metrics": initial_body["metrics"],
    }
    warnings = body["warnings"]
    if design.selection == "minimum_energy":
        within = " within the limits" if any(v is not None for v in request.limits.model_dump().values()) else ""
        warnings.append(
            f"no zero-energy design was found{within}; this one leaves {100 * design.energy_ratio:.3g} % of the "
            "initial design's vibration energy"
        )
    limits = request.limits
    for name, limit, values in (
        ("max_velocity", limits.max_velocity, body["profile"]["velocity"]),
        ("max_acceleration", limits.max_acceleration, body["profile"]["acceleration"]),
        ("max_jerk", limits.max_jerk, body["profile"]["jerk"]),
        ("max_torque_nm", limits.max_torque_nm, body["load"]["motor_torque_nm"]),
    ):
        if limit is not None and values is not None and float(np.max(np.abs(values))) > limit * (1 + 1e-9):
            warnings.append(f"limits.{name} is exceeded by the samples: peak {float(np.max(np.abs(values))):.6g}")
    return body


async def respond(request: PseudoPolynomialIn, settings: Settings, pool: SolverPool) -> dict[str, Any]:
    """The full response body (used by the route and by /v1/compare)."""
    plant = to_plant(request.plant)
    core = core_request(request, plant, settings)
    sample_count_check(_horizon(request, plant, request.duration_s), request.sample_period_s, settings.max_samples)
    deadline = 4.0 * settings.solve_time_limit_s + settings.solve_grace_s
    design = await pool.run(synthesis.design, core, deadline_s=deadline)
    return await run_in_threadpool(compose, request, plant, design, settings)


@router.post(
    "/profiles/pseudo-polynomial",
    summary="Pseudo-polynomial command with no residual vibration (Incerti)",
    response_model=PseudoPolynomialOut,
    responses={**CSV_RESPONSE_DOC, **problems.responses(413, 422, 503, 504)},
)
async def pseudo_polynomial(
    body: Annotated[PseudoPolynomialIn, Body(openapi_examples=EXAMPLES)],
    request: Request,
    settings: Annotated[Settings, Depends(get_settings)],
    format: CsvFormat = None,
) -> Response:
    """Chooses the exponents of phi(t) = Phi [1 - sum C_i (1 - t/T)^gamma_i] so that the plant is left
    with no vibration energy when the move ends, within the limits, by IPOPT in a worker process.

    The returned profile holds the law's exact values at the sample times; the load response simulates
    the drive following them (velocity on the cubic Hermite curve through the sampled velocities and
    accelerations). A failed or timed-out solve is a problem, never a profile."""
    return negotiate(request, await respond(body, settings, request.app.state.pool), "pseudo-polynomial profile")
