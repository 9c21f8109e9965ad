"""Trajectory smoothers (Biagiotti, Melchiorri and Moriello 2020): POST /v1/profiles/smoother.

Where the service departs from the paper: vibration-free durations of the (damped) harmonic smoother
are odd multiples (2m+1) pi/Omega, m >= 1 (eqs. 13 and 15 also allow even multiples, which leave a
clear residual); eq. (17)'s rounding N = round(T/Ts) is reported with the residual it leaves and the
sample period that avoids it.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Depends
from starlette.responses import Response

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples.smoother import EXAMPLES as SMOOTHER_EXAMPLES
from app.family_names import slug_of
from app.json_bodies import JSONRoute
from app.responses import CSV_RESPONSE_DOC, Output, ProfileOutput, respond
from app.schemas.smoothers import FAMILY, SmootherRequest, SmootherResponse
from app.services import profile as profiles

router = APIRouter(prefix="/v1", tags=["smoothers"], route_class=JSONRoute)


@router.post(
    f"/profiles/{slug_of(FAMILY.name)}",
    summary="Smoother chain (rectangular, harmonic, damped harmonic, exponential filters) for a rest-to-rest move",
    response_model=SmootherResponse,
    responses={**CSV_RESPONSE_DOC, **problems.responses(413, 422)},
)
async def smoother_profile(
    body: Annotated[SmootherRequest, Body(openapi_examples=SMOOTHER_EXAMPLES)],
    settings: SettingsDep,
    pool: PoolDep,
    threads: ThreadsDep,
    output: Annotated[Output, Depends(ProfileOutput(SmootherResponse))],
) -> Response:
    """A step of ``displacement`` filtered by a chain of FIR smoothers (Biagiotti et al. 2020).

    Filters without a duration are tuned to the plant's first mode: the damped harmonic smoother with
    T = 3 pi/Omega and sigma = -zeta omega_n cancels it exactly (eqs. 10-11). Rectangular filters are added in
    front for the kinematic limits (eqs. 2-3, 6). The profile is exact at its samples (the period asked
    plus every filter breakpoint); between samples the command is the exact polynomial of a rectangular
    chain, or else the degree-7 Taylor polynomial of the exact derivatives, which the load simulation and
    the metrics use. ``design.residual_amplitude_closed_form`` gives the same residual from the chain's
    transfer function at the plant's poles.
    """
    answer, result = await profiles.design(FAMILY, body, settings, pool, threads)
    return await respond(output, answer, result, body, "smoother profile")
