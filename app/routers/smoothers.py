"""Trajectory smoothers (Biagiotti, Melchiorri and Moriello 2020): POST /v1/profiles/smoother.

Where the service departs from the paper: vibration-free durations of the (damped) harmonic smoother
are odd multiples (2m+1) pi/Omega, m >= 1 (eqs. 13 and 15 also allow even multiples, which leave a
clear residual); eq. (17)'s rounding N = round(T/Ts) is reported with the residual it leaves and the
sample period that avoids it.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, Depends
from starlette.responses import Response

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples import BIAGIOTTI_PLANT, T0_S
from app.responses import CSV_RESPONSE_DOC, Output, ProfileOutput, respond
from app.schemas.smoothers import FAMILY, SmootherRequest, SmootherResponse
from app.services import profile as profiles

router = APIRouter(prefix="/v1", tags=["smoothers"], route_class=problems.JSONRoute)

SMOOTHER_EXAMPLES: dict[str, dict[str, Any]] = {
    "biagiotti_damped_harmonic": {
        "summary": "Sec. VI: damped harmonic smoother on the identified plant, 30 mm step",
        "description": "sigma = -15.6539 1/s and Omega = 122.7185 rad/s give T0 = 0.0512 s and T1 = 1.5 T0 = 0.0768 s. "
        "The smoother cancels the mode: the residual is zero to round-off. The discrete filter at the "
        "experiment's Ts = 0.5 ms (eq. 17) rounds T1/Ts = 153.6 to 154 samples, which leaves 0.27 % of the "
        "unfiltered vibration; exact_sample_period_s avoids it.",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 0.03,
            "filters": [{"type": "damped_harmonic"}],
            "sample_period_s": 0.0005,
            "discrete_sample_period_s": 0.0005,
            "sensitivity": {"min_ratio": 0.5, "max_ratio": 1.5, "count": 101},
        },
    },
    "biagiotti_harmonic": {
        "summary": "Sec. VI: undamped harmonic smoother on the same plant",
        "description": "T = 3 pi/Omega = 0.0768 s, but S cannot cancel a damped mode: about 4.3 % of the 30 mm "
        "step is left (Fig. 17 (d) against (e)).",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 0.03,
            "filters": [{"type": "harmonic"}],
            "sample_period_s": 0.0005,
        },
    },
    "biagiotti_exponential_pair": {
        "summary": "Sec. V: two exponential filters M_sigma,1 M_sigma,2 (T0 and T0/2)",
        "description": "The damped generalisation of M1 M2 with T1 = T0 = 0.0512 s, compared with S_sigma in Fig. 13.",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 0.03,
            "filters": [{"type": "exponential"}, {"type": "exponential", "duration_s": round(T0_S / 2, 10)}],
            "sample_period_s": 0.0005,
        },
    },
    "limits_and_vibration": {
        "summary": "Damped harmonic smoother under velocity and acceleration limits",
        "description": "Rectangular filters are put in front of the tuned smoother so that |v| <= 0.3 m/s and "
        "|a| <= 10 m/s^2 (eqs. 2-3 extended to the chain); the mode stays cancelled.",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 0.03,
            "filters": [{"type": "damped_harmonic"}],
            "limits": {"max_velocity": 0.3, "max_acceleration": 10.0},
            "sample_period_s": 0.0005,
        },
    },
    "kinematic_chain": {
        "summary": "Sec. II: time-optimal chain for v = 1, a = 2, j = 8 and h = 1",
        "description": "No vibration filter: three rectangular filters T = (1, 0.5, 0.25) s (eq. 2; eq. 3 holds).",
        "value": {
            "plant": BIAGIOTTI_PLANT,
            "displacement": 1.0,
            "filters": [],
            "limits": {"max_velocity": 1.0, "max_acceleration": 2.0, "max_jerk": 8.0},
            "sample_period_s": 0.01,
        },
    },
}


@router.post(
    "/profiles/smoother",
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
