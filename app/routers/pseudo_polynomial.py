"""POST /v1/profiles/pseudo-polynomial: Incerti's commands with exponents chosen by IPOPT."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, Depends, Response

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples import CUSIMANO_8HZ, INCERTI_TABLE_III
from app.responses import CSV_RESPONSE_DOC, Output, ProfileOutput, respond
from app.schemas.pseudo_polynomial import FAMILY, PseudoPolynomialIn, PseudoPolynomialOut
from app.services import profile as profiles

router = APIRouter(prefix="/v1", tags=["pseudo-polynomial"], route_class=problems.JSONRoute)

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


@router.post(
    "/profiles/pseudo-polynomial",
    summary="Pseudo-polynomial command with no residual vibration (Incerti)",
    response_model=PseudoPolynomialOut,
    responses={**CSV_RESPONSE_DOC, **problems.responses(413, 422, 503, 504)},
)
async def pseudo_polynomial_profile(
    body: Annotated[PseudoPolynomialIn, Body(openapi_examples=EXAMPLES)],
    settings: SettingsDep,
    pool: PoolDep,
    threads: ThreadsDep,
    output: Annotated[Output, Depends(ProfileOutput(PseudoPolynomialOut))],
) -> Response:
    """Chooses the exponents of phi(t) = Phi [1 - sum C_i (1 - t/T)^gamma_i] so that the plant is left
    with no vibration energy when the move ends, within the limits, by IPOPT in a worker process.

    The returned profile holds the law's exact values at the sample times; the load response simulates
    the drive following them (velocity on the cubic Hermite curve through the sampled velocities and
    accelerations). A failed or timed-out solve is a problem, never a profile."""
    answer, result = await profiles.design(FAMILY, body, settings, pool, threads)
    return await respond(output, answer, result, body, "pseudo-polynomial profile")
