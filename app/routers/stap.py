"""POST /v1/profiles/stap: symmetric trapezoidal acceleration profiles (Cusimano 2022)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, Depends, Response

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples import CUSIMANO_8HZ, CUSIMANO_40HZ
from app.responses import CSV_RESPONSE_DOC, Output, ProfileOutput, respond
from app.schemas.stap import FAMILY, StapIn, StapOut
from app.services import profile as profiles

router = APIRouter(prefix="/v1", tags=["stap"], route_class=problems.JSONRoute)

CUSIMANO_8HZ_LIGHT_LOAD: dict[str, Any] = {
    "kind": "two_inertia",
    "motor_inertia_kgm2": 0.005,
    "load_inertia_kgm2": 0.00125,
    "stiffness_nm_per_rad": 3.158273408,  # J_L (2 pi 8 Hz)^2 with J_L = J_M/4
    "damping_nms_per_rad": 0.0,
}
_SEC3 = {"plant": CUSIMANO_40HZ, "target_velocity": 150.0, "limits": {"max_acceleration": 1000.0}}

EXAMPLES: dict[str, dict[str, Any]] = {
    "section_3_k1": {
        "summary": "Sec. 3 (Fig. 14): 150 rad/s on a 40 Hz mode, a_Max = 1000 rad/s^2, k_j = 1",
        "description": "t_a,min = 0.15 s (eq. 21), t_j = 1/f_n,e = 0.025 s (eq. 50), t_a = 0.175 s (eq. 61): "
        "no residual.",
        "value": {**_SEC3, "jerk_periods": 1, "sensitivity": {"min_ratio": 0.5, "max_ratio": 1.5, "count": 201}},
    },
    "section_3_k3": {
        "summary": "Sec. 3 (Fig. 16): the same with k_j = 3 (t_j = 0.075 s, t_a = 0.225 s)",
        "value": {**_SEC3, "jerk_periods": 3},
    },
    "fig_17_side_band": {
        "summary": "Fig. 17: t_a = 0.165 s with the side band (k_j, delta) = (0, 1): "
        "t_j = dec(f_n,e t_a)/f_n,e = 0.015 s",
        "description": "Zero residual at f_n,e, but the load acceleration oscillates during t_c and the SC is poor "
        "(Appendix C: f_n,e t_a,min = 6 is whole and 0.15 <= t_a < 0.175).",
        "value": {**_SEC3, "acceleration_time_s": 0.165, "jerk_periods": 0, "delta": 1},
    },
    "table_2_torque_limit": {
        "summary": "Sec. 3: Table 2 motor (10 N m) with J_L = J_M at 8 Hz; the limit lowered for 0.9 f_n,e",
        "description": "a_Max = 10/(J_M + J_L) = 1000 rad/s^2 (eq. 19), t_a,min = 0.15 s; the torque oscillates "
        "by about 0.055 M at 0.9 f_n,e (eqs. 57-59), so the limit is lowered to 0.948 of it (the paper's 0.94).",
        "value": {
            "plant": CUSIMANO_8HZ,
            "target_velocity": 150.0,
            "limits": {"max_torque_nm": 10.0},
            "jerk_periods": 1,
        },
    },
    "table_2_light_load": {
        "summary": "Sec. 3: the same motor with J_L = J_M/4: a triangle peaking at 1200 rad/s^2 (eq. 31)",
        "value": {
            "plant": CUSIMANO_8HZ_LIGHT_LOAD,
            "target_velocity": 150.0,
            "limits": {"max_torque_nm": 10.0},
            "jerk_periods": 1,
        },
    },
    "auto": {
        "summary": "The Fig. 25 flowchart: k_j chosen for a 10 % frequency uncertainty and a 5 % residual",
        "value": {**_SEC3, "frequency_uncertainty": 0.1, "residual_tolerance": 0.05},
    },
    "damped_optimized": {
        "summary": "A damped 40 Hz mode (zeta = 0.1), t_a = 0.2 s: IPOPT over t_j beats the k_j = 1 closed form",
        "value": {
            **_SEC3,
            "plant": {"kind": "mode", "natural_frequency_hz": 40.0, "damping_ratio": 0.1},
            "acceleration_time_s": 0.2,
            "jerk_periods": 1,
            "method": "optimized",
        },
    },
    "robust_optimized": {
        "summary": "Worst case over +-20 % of f_n,e and zeta in {0, 0.05}, at t_a = 0.2 s",
        "value": {
            **_SEC3,
            "acceleration_time_s": 0.2,
            "method": "optimized",
            "frequency_uncertainty": 0.2,
            "optimization": {"objective": "worst_case", "damping_ratios": [0.0, 0.05]},
        },
    },
    "rest_to_rest": {
        "summary": "Rest-to-rest: 30 rad at up to 150 rad/s on the 40 Hz mode (two k_j = 1 ramps and a cruise)",
        "value": {
            "plant": CUSIMANO_40HZ,
            "displacement": 30.0,
            "limits": {"max_acceleration": 1000.0, "max_velocity": 150.0},
            "jerk_periods": 1,
        },
    },
}


@router.post(
    "/profiles/stap",
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
