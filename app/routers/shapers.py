"""Input shapers under an acceleration limit (Chatlatanagulchai & Pongpanich): GET /v1/shapers and
POST /v1/profiles/input-shaped."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Depends, Query, Response

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples.input_shaped import EXAMPLES as INPUT_SHAPED_EXAMPLES
from app.family_names import slug_of
from app.json_bodies import JSONRoute
from app.responses import CSV_RESPONSE_DOC, NumpyJSONResponse, Output, ProfileOutput, respond
from app.schemas.shapers import FAMILY, InputShapedRequest, InputShapedResponse, ShaperCatalogue
from app.services import profile as profiles
from app.services import shapers

router = APIRouter(prefix="/v1", tags=["shapers"], route_class=JSONRoute)


@router.post(
    f"/profiles/{slug_of(FAMILY.name)}",
    summary="Input-shaped velocity command under an acceleration limit (Chatlatanagulchai & Pongpanich)",
    response_model=InputShapedResponse,
    responses={**CSV_RESPONSE_DOC, **problems.responses(413, 422)},
)
async def input_shaped_profile(
    body: Annotated[InputShapedRequest, Body(openapi_examples=INPUT_SHAPED_EXAMPLES)],
    settings: SettingsDep,
    pool: PoolDep,
    threads: ThreadsDep,
    output: Annotated[Output, Depends(ProfileOutput(InputShapedResponse))],
) -> Response:
    """Shape a velocity step or a rest-to-rest move for the plant's mode(s) and keep it within the
    drive's acceleration limit.

    The shaped command v_s (``profile``) is the baseline v_b (``baseline``) convolved with the
    impulses. The default baseline ``auto`` is the earliest-ending one whose shaped command meets the
    limits, so the drive passes it unchanged: the ``modified`` ramp of Sec. 4 (Delta = a1 max|A_i| / a)
    where the no-overlap condition t_(i+1) - t_i >= Delta holds (the paper prints |A_i| in place of
    max|A_i| there), else a longer single ramp or a multi-step baseline; ``design.baseline`` says which
    and why. A rest-to-rest move cruises at the fastest speed within ``limits.max_velocity``. Asked
    for explicitly, ``modified`` refuses as infeasible where its ramps would overlap; ``multi_step``
    uses the paper's two-step relations only where they hold (two impulses with A1 >= A2, as ZV), and
    otherwise (ZVD, where they give a negative step and a slope of 2a) the fastest valid steps.
    A command beyond the limit (``step``) is changed by the drive (``rate_limited``): a rate limiter
    for a velocity step (Fig. 5); for a rest-to-rest move a position-mode drive whose profile
    generator follows the shaped position reference time-optimally and arrives at the displacement.
    The load response and ``metrics`` simulate what the drive does, exactly; ``unmodified`` gives the
    metrics of the plain shaped step after the drive, for comparison.
    """
    answer, result = await profiles.design(FAMILY, body, settings, pool, threads)
    return await respond(output, answer, result, body, "input-shaped profile (the shaped command sent to the drive)")


# ------------------------------------------------------------------------------------------
# The catalogue


@router.get(
    "/shapers",
    summary="The shaper family: impulse counts, durations and computed 5 % bands",
    response_model=ShaperCatalogue,
    responses=problems.responses(422),
)
def list_shapers(
    damping_ratio: Annotated[float, Query(ge=0.0, le=0.9, description="Design damping ratio zeta.")] = 0.0,
    vibration_tolerance: Annotated[float, Query(ge=0.001, le=0.3, description="Tolerance of the EI shapers.")] = 0.05,
) -> NumpyJSONResponse:
    """Every shaper designed for a unit mode with this damping. Each band is computed from the
    percentage vibration V (Sec. 3.1) of its impulses, with the damping fixed: the ratios of true
    to design natural frequency around 1 where V stays <= 5 %. EI shapers that do not exist at this
    damping and tolerance are listed under ``unavailable``."""
    return NumpyJSONResponse(shapers.catalogue_answer(float(damping_ratio), float(vibration_tolerance)))
