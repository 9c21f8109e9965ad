"""POST /v1/profiles/stap: symmetric trapezoidal acceleration profiles (Cusimano 2022)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Depends, Response

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples.stap import EXAMPLES
from app.family_names import slug_of
from app.json_bodies import JSONRoute
from app.responses import CSV_RESPONSE_DOC, Output, ProfileOutput, respond
from app.schemas.stap import FAMILY, StapIn, StapOut
from app.services import profile as profiles

router = APIRouter(prefix="/v1", tags=["stap"], route_class=JSONRoute)


@router.post(
    f"/profiles/{slug_of(FAMILY.name)}",
    summary="Symmetric trapezoidal acceleration profile without residual vibration (Cusimano)",
    response_model=StapOut,
    responses={**CSV_RESPONSE_DOC, **problems.responses(413, 422, 503, 504)},
)
async def stap_profile(
    body: Annotated[StapIn, Body(openapi_examples=EXAMPLES)],
    settings: SettingsDep,
    pool: PoolDep,
    threads: ThreadsDep,
    output: Annotated[Output, Depends(ProfileOutput(StapOut))],
) -> Response:
    """Designs t_a and t_j of a symmetric trapezoidal acceleration profile (rest-to-velocity, or a rest-to-rest
    move made of two of them and a cruise) so that the load is left without vibration at the estimated
    frequency f_n,e, within the acceleration and torque limits.

    closed_form applies the paper's rules in the request (t_a,min = v/a_Max, eq. 21; t_j = k_j/f_n,e, eq. 50;
    t_a by eq. 61 or the triangle of eq. 66; a caller-fixed t_a with its zero-vibration jerk times, eqs. 44-49,
    side bands and Appendix C marked; auto = the Fig. 25 flowchart, see design.auto_rule); with max_torque_nm
    the limit is eq. (19) lowered by the torque oscillation of eqs. (57)-(59). optimized solves a CasADi/IPOPT
    problem over (t_a, t_j) in a worker process. Departures from the paper: eqs. (45)-(46) are reported but the
    zero-vibration jerk times are found by enumeration (eq. 46 can name a zero beyond t_j,max); the 'auto'
    tolerance formalises "a few hundredths"; the torque rule gives 0.948 where the paper rounds to 0.94.

    The profile holds the exact STAP at the sample times (corners always included): with the acceleration
    held linearly between samples it is the designed command, which load and metrics simulate exactly."""
    answer, result = await profiles.design(FAMILY, body, settings, pool, threads)
    return await respond(output, answer, result, body, "STAP profile")
