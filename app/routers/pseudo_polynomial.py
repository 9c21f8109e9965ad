"""POST /v1/profiles/pseudo-polynomial: Incerti's commands with exponents chosen by IPOPT."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Depends, Response

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples.pseudo_polynomial import EXAMPLES
from app.family_names import slug_of
from app.json_bodies import JSONRoute
from app.responses import CSV_RESPONSE_DOC, Output, ProfileOutput, respond
from app.schemas.pseudo_polynomial import FAMILY, PseudoPolynomialIn, PseudoPolynomialOut
from app.services import profile as profiles

router = APIRouter(prefix="/v1", tags=["pseudo-polynomial"], route_class=JSONRoute)


@router.post(
    f"/profiles/{slug_of(FAMILY.name)}",
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
