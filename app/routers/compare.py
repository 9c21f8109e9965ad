"""POST /v1/compare: every family that applies, on one plant, one move and one set of limits.

Each family is run through its own endpoint's ``respond`` with a request built here, and the row
is read from that response, so a row's numbers are exactly what the family endpoint returns for
the request echoed in ``rows[].request``.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Body, Depends, Request
from pydantic import BaseModel, Field, ValidationError, model_validator
from starlette.concurrency import run_in_threadpool

from app import problems
from app.examples import CUSIMANO_8HZ, INCERTI_TABLE_III
from app.responses import NumpyJSONResponse
from app.routers import pseudo_polynomial, shapers, smoothers, stap
from app.schemas.common import OutModel, StrictModel
from app.schemas.family import LimitsIn, SensitivityOut
from app.schemas.plants import PlantIn, to_plant
from app.schemas.pseudo_polynomial import PseudoPolynomialIn
from app.schemas.shapers import InputShapedRequest
from app.schemas.simulate import LoadOut, ProfileOut
from app.schemas.smoothers import SmootherRequest
from app.schemas.stap import StapIn
from app.settings import Settings, get_settings
from models.errors import Infeasible, InvalidParameter
from models.plants import Plant
from optim.solver import SolverFailed, SolverTimedOut
from optim.workers import SolveTimeout

router = APIRouter(prefix="/v1", tags=["compare"])
Family = Literal["pseudo_polynomial", "stap", "smoother", "input_shaped"]
SENSITIVITY = {"min_ratio": 0.5, "max_ratio": 1.5, "count": 201}
MIN_PERIOD_S = 1e-6


class CompareIn(StrictModel):
    """One plant, one move (displacement for rest-to-rest, or target_velocity) and one set of limits."""

    plant: PlantIn
    displacement: float | None = Field(None, description="Rest-to-rest move of the motor, rad or m.")
    target_velocity: float | None = Field(None, description="Rest-to-velocity move: final motor speed.")
    limits: LimitsIn = Field(default_factory=LimitsIn)
    duration_s: float | None = Field(
        None,
        gt=0,
        le=1e5,
        description="Duration of the pseudo-polynomial move (default: the shortest within the limits).",
    )
    families: list[Family] | None = Field(None, min_length=1, description="Run only these families (default: all).")
    sample_period_s: float | None = Field(
        None, ge=1e-6, le=10, description="Sample period (default: about 500 samples per move)."
    )
    settling_tolerance: float = Field(1e-3, gt=0, le=1, description="Settling band as a fraction of the move.")
    include_curves: bool = Field(False, description="Add each design's profile, load response and sensitivity curve.")

    @model_validator(mode="after")
    def _one_move(self) -> CompareIn:
        if (self.displacement is None) == (self.target_velocity is None):
            raise ValueError("give exactly one of displacement (rest-to-rest) or target_velocity (rest-to-velocity)")
        move = self.displacement if self.displacement is not None else self.target_velocity
        if move == 0 or not math.isfinite(move) or abs(move) > 1e9:
            raise ValueError("the move must be non-zero and within +-1e9")
        return self


class Curves(OutModel):
    profile: ProfileOut
    load: LoadOut
    sensitivity: SensitivityOut | None


class Row(OutModel):
    family: Family
    endpoint: str = Field(description="The family endpoint; POST `request` there to get this design.")
    request: dict[str, Any]
    motion_time_s: float = Field(description="Until the command's last change.")
    settling_time_s: float | None = Field(description="Load within the settling band, from the start; null if never.")
    residual_vibration: float = Field(description="Residual at the nominal frequency, fraction of the move.")
    residual_amplitude: float = Field(
        description="Load free-oscillation envelope (position; velocity for rest-to-velocity)."
    )
    band_5_percent: list[float | None] | None = Field(
        description="f_n/f_n,e range around 1 where the residual stays <= 5 % (evaluated on 0.5..1.5; an end is "
        "null where the band runs past that range)."
    )
    peak_velocity: float | None
    peak_acceleration: float | None
    peak_jerk: float | None
    peak_motor_torque_nm: float | None
    limits_met: bool
    limit_violations: list[str]
    warnings: list[str]
    curves: Curves | None = None


class Unavailable(OutModel):
    family: Family
    reason: str
    problem_type: str | None = None


class CompareOut(OutModel):
    move: Literal["rest_to_rest", "rest_to_velocity"]
    rows: list[Row] = Field(description="Sorted by settling time (never-settling designs last).")
    unavailable: list[Unavailable]


@dataclass(frozen=True)
class Runner:
    family: Family
    endpoint: str
    schema: type[BaseModel]
    build: Callable[[CompareIn, Plant, float], dict[str, Any] | str]  # a request body, or why it does not apply
    respond: Callable[[Any, Settings, Any], Awaitable[dict[str, Any]]]


def nice_period(span_s: float, samples: int = 500) -> float:
    """A round sample period (1, 2 or 5 times a power of ten) giving about ``samples`` over the
    span, and never below the families' floor of 1 microsecond."""
    raw = max(span_s / samples, MIN_PERIOD_S)
    exponent = math.floor(math.log10(raw))
    for mantissa in (1.0, 2.0, 5.0, 10.0):
        if mantissa * 10**exponent >= raw:
            return mantissa * 10**exponent
    return 10.0 ** (exponent + 1)


def kinematic_floor(request: CompareIn) -> float:
    """The least duration any rest-to-rest move (or acceleration phase) can have within the limits."""
    lim = request.limits
    if request.displacement is not None:
        d = abs(request.displacement)
        floors = [d / lim.max_velocity] if lim.max_velocity else []
        floors += [2 * math.sqrt(d / lim.max_acceleration)] if lim.max_acceleration else []
        floors += [(32 * d / lim.max_jerk) ** (1 / 3)] if lim.max_jerk else []
    else:
        v = abs(request.target_velocity or 0.0)
        floors = [v / lim.max_acceleration] if lim.max_acceleration else []
        floors += [2 * math.sqrt(v / lim.max_jerk)] if lim.max_jerk else []
    return max(floors, default=0.0)


def _pseudo_polynomial(request: CompareIn, plant: Plant, period_s: float) -> dict[str, Any] | str:
    if request.displacement is None:
        return "pseudo-polynomial commands are rest-to-rest moves; give a displacement"
    mode_period = plant.modes()[0].natural_period_s
    body: dict[str, Any] = {
        "plant": request.plant.model_dump(),
        "displacement": request.displacement,
        "limits": request.limits.model_dump(exclude_none=True),
        "sample_period_s": period_s,
        "settling_tolerance": request.settling_tolerance,
        "sensitivity": SENSITIVITY,
    }
    if request.duration_s is not None:
        body["duration_s"] = request.duration_s
    elif any(v is not None for v in request.limits.model_dump().values()):
        # Start the shortest-duration search at whole periods (where order-2 zero-energy designs live).
        start = max(2 * kinematic_floor(request), 5 * mode_period)
        body["duration_s"] = mode_period * math.ceil(start / mode_period - 1e-9)
        body["minimize_duration"] = True
    else:
        body["duration_s"] = 5 * mode_period
    return body


def _smoother(request: CompareIn, plant: Plant, period_s: float) -> dict[str, Any] | str:
    if request.displacement is None:
        return "the smoother family shapes rest-to-rest moves (a filtered position step); give a displacement"
    return {
        "plant": request.plant.model_dump(),
        "displacement": request.displacement,
        "filters": [{"type": "damped_harmonic"}],  # tuned to the plant: 3 pi/Omega, sigma = -zeta omega_n
        # The family designs for velocity, acceleration and jerk; the torque is checked on the result.
        "limits": request.limits.model_dump(exclude_none=True, exclude={"max_torque_nm"}),
        "sample_period_s": period_s,
        "sensitivity": SENSITIVITY,
    }


def acceleration_limit(request: CompareIn, plant: Plant) -> float | None:
    """max_acceleration, or for a two-inertia plant with a torque limit, M / (J_M + J_L) (Cusimano eq. 19)."""
    inertias = plant.torque_inertias()
    candidates = [request.limits.max_acceleration] if request.limits.max_acceleration else []
    if request.limits.max_torque_nm is not None and inertias is not None:
        candidates.append(request.limits.max_torque_nm / sum(inertias))
    return min(candidates) if candidates else None


def _stap(request: CompareIn, plant: Plant, period_s: float) -> dict[str, Any] | str:
    torque = request.limits.max_torque_nm if plant.torque_inertias() is not None else None
    if request.limits.max_acceleration is None and torque is None:
        return "a STAP is designed from the acceleration limit: give max_acceleration (or max_torque_nm on a two_inertia plant)"
    body: dict[str, Any] = {
        "plant": request.plant.model_dump(),
        "jerk_periods": "auto",
        "method": "closed_form",
        "sample_period_s": period_s,
        "settling_tolerance": request.settling_tolerance,
        "sensitivity": SENSITIVITY,
    }
    if request.limits.max_acceleration is not None:
        body["max_acceleration"] = request.limits.max_acceleration
    if torque is not None:
        body["max_torque_nm"] = torque
    if request.displacement is not None:
        body["displacement"] = request.displacement
        if request.limits.max_velocity is not None:
            body["target_velocity"] = math.copysign(request.limits.max_velocity, request.displacement)
    else:
        body["target_velocity"] = request.target_velocity
    return body


def _input_shaped(request: CompareIn, plant: Plant, period_s: float) -> dict[str, Any] | str:
    accel = acceleration_limit(request, plant)
    body: dict[str, Any] = {
        "plant": request.plant.model_dump(),
        "shaper": "zvd",
        "baseline": "modified" if accel is not None else "step",
        "sample_period_s": period_s,
        "settling_tolerance": request.settling_tolerance,
        "sensitivity": SENSITIVITY,
    }
    if accel is not None:
        body["acceleration_limit"] = accel
    if request.displacement is not None:
        body["displacement"] = request.displacement
        if request.limits.max_velocity is not None:
            body["cruise_velocity"] = request.limits.max_velocity
    else:
        body["target_velocity"] = request.target_velocity
    return body


async def _respond_shaped(request: InputShapedRequest, settings: Settings, pool: Any) -> dict[str, Any]:
    return await run_in_threadpool(shapers.respond, request, settings)


RUNNERS: dict[str, Runner] = {
    "pseudo_polynomial": Runner(
        "pseudo_polynomial",
        "/v1/profiles/pseudo-polynomial",
        PseudoPolynomialIn,
        _pseudo_polynomial,
        pseudo_polynomial.respond,
    ),
    "stap": Runner("stap", "/v1/profiles/stap", StapIn, _stap, stap.respond),
    "smoother": Runner("smoother", "/v1/profiles/smoother", SmootherRequest, _smoother, smoothers.respond_async),
    "input_shaped": Runner(
        "input_shaped", "/v1/profiles/input-shaped", InputShapedRequest, _input_shaped, _respond_shaped
    ),
}
# When a family's first request is infeasible, the request to try instead (and why).
FALLBACKS: dict[str, Callable[[dict[str, Any]], dict[str, Any] | None]] = {
    # The modified baseline needs t_(i+1) - t_i >= Delta; a single slower ramp always exists.
    "input_shaped": lambda body: (
        {**body, "baseline": "multi_step", "baseline_steps": 1} if body.get("baseline") == "modified" else None
    ),
}


def _reason(exc: Exception) -> str:
    """A failure in the user's terms: the field and the rule for invalid input."""
    if isinstance(exc, ValidationError):
        return "; ".join(f"{'.'.join(str(p) for p in e['loc']) or 'request'}: {e['msg']}" for e in exc.errors()[:3])
    if isinstance(exc, InvalidParameter):
        return f"{exc.field}: {exc.rule}"
    return str(exc)


def _problem_type(exc: Exception) -> str:
    if isinstance(exc, Infeasible):
        return "/problems/infeasible"
    if isinstance(exc, SolveTimeout):
        return "/problems/solve-timeout"
    if isinstance(exc, SolverFailed):
        return "/problems/solve-timeout" if isinstance(exc, SolverTimedOut) else "/problems/solver-failed"
    return "/problems/invalid-input"


def _limits_report(request: CompareIn, metrics: dict[str, Any]) -> list[str]:
    pairs = (
        ("max_velocity", "peak_velocity"),
        ("max_acceleration", "peak_acceleration"),
        ("max_jerk", "peak_jerk"),
        ("max_torque_nm", "peak_motor_torque_nm"),
    )
    out = []
    for limit_name, peak_name in pairs:
        limit = getattr(request.limits, limit_name)
        if limit is None:
            continue
        peak = metrics.get(peak_name)
        if peak is None:
            out.append(
                f"{limit_name}: the {peak_name.removeprefix('peak_').replace('_', ' ')} is impulsive or undefined"
            )
        elif peak > limit * (1 + 1e-9):
            out.append(f"{limit_name}: peak {peak:.6g} > {limit:.6g}")
    return out


def _row(runner: Runner, request: CompareIn, body: dict[str, Any], family_request: dict[str, Any]) -> dict[str, Any]:
    metrics = body["metrics"]
    velocity_move = request.target_velocity is not None
    move = request.target_velocity if velocity_move else request.displacement
    amplitude = metrics["residual_velocity_amplitude"] if velocity_move else metrics["residual_amplitude"]
    load_scale = to_plant(request.plant).load_move(move)  # type: ignore[arg-type]
    violations = _limits_report(request, metrics)
    sensitivity = body.get("sensitivity")
    row = {
        "family": runner.family,
        "endpoint": runner.endpoint,
        "request": family_request,
        "motion_time_s": metrics["command_end_s"] - float(body["profile"]["time_s"][0]),
        "settling_time_s": metrics["settling_time_s"],
        "residual_vibration": amplitude / load_scale,
        "residual_amplitude": amplitude,
        "band_5_percent": sensitivity["band_5_percent"] if sensitivity else None,
        "peak_velocity": metrics["peak_velocity"],
        "peak_acceleration": metrics["peak_acceleration"],
        "peak_jerk": metrics["peak_jerk"],
        "peak_motor_torque_nm": metrics["peak_motor_torque_nm"],
        "limits_met": not violations,
        "limit_violations": violations,
        "warnings": body.get("warnings", []),
    }
    if request.include_curves:
        row["curves"] = {"profile": body["profile"], "load": body["load"], "sensitivity": sensitivity}
    return row


async def _run(
    runner: Runner, request: CompareIn, plant: Plant, period_s: float, settings: Settings, pool: Any
) -> dict[str, Any]:
    built = runner.build(request, plant, period_s)
    if isinstance(built, str):
        return {"unavailable": {"family": runner.family, "reason": built}}
    try:
        try:
            body = await runner.respond(runner.schema.model_validate(built), settings, pool)
        except Infeasible:
            fallback = FALLBACKS.get(runner.family, lambda _: None)(built)
            if fallback is None:
                raise
            built = fallback
            body = await runner.respond(runner.schema.model_validate(built), settings, pool)
    except (Infeasible, InvalidParameter, SolverFailed, SolveTimeout, ValidationError) as exc:
        return {"unavailable": {"family": runner.family, "reason": _reason(exc), "problem_type": _problem_type(exc)}}
    return {"row": _row(runner, request, body, built)}


EXAMPLES: dict[str, dict[str, Any]] = {
    "incerti_rest_to_rest": {
        "summary": "Incerti Table III platform: 15 motor revolutions within velocity and acceleration limits",
        "value": {
            "plant": INCERTI_TABLE_III,
            "displacement": 94.24777960769379,
            "limits": {"max_velocity": 200.0, "max_acceleration": 700.0},
        },
    },
    "cusimano_rest_to_velocity": {
        "summary": "Cusimano 8 Hz two-inertia plant: up to 150 rad/s within the 10 N m motor",
        "value": {"plant": CUSIMANO_8HZ, "target_velocity": 150.0, "limits": {"max_torque_nm": 10.0}},
    },
}


@router.post(
    "/compare",
    summary="Every family side by side on one plant, move and limits",
    response_model=CompareOut,
    responses=problems.responses(413, 422, 503),
)
async def compare(
    request: Annotated[CompareIn, Body(openapi_examples=EXAMPLES)],
    http: Request,
    settings: Annotated[Settings, Depends(get_settings)],
) -> NumpyJSONResponse:
    """Runs every family that applies (pseudo-polynomial needs a rest-to-rest move) with the same
    limits, and returns one row per design sorted by the load's settling time. A family that
    cannot meet the limits is listed in `unavailable` with its reason. `rows[].request` is the
    exact request to POST to `rows[].endpoint` to get the same design (add `?format=csv` for a
    cam table)."""
    plant = to_plant(request.plant)
    if not plant.modes():
        raise InvalidParameter("plant", plant.kind, "the plant has no vibration mode to design against")
    mode_period = plant.modes()[0].natural_period_s
    period_s = request.sample_period_s or nice_period(
        max(2 * kinematic_floor(request), 5 * mode_period) + 5 * mode_period
    )
    wanted = request.families or list(RUNNERS)
    results = await asyncio.gather(
        *(_run(RUNNERS[f], request, plant, period_s, settings, http.app.state.pool) for f in wanted if f in RUNNERS)
    )
    rows = [r["row"] for r in results if "row" in r]
    rows.sort(key=lambda r: (r["settling_time_s"] is None, r["settling_time_s"] or 0.0))
    unavailable = [r["unavailable"] for r in results if "unavailable" in r]
    return NumpyJSONResponse(
        {
            "move": "rest_to_velocity" if request.target_velocity is not None else "rest_to_rest",
            "rows": rows,
            "unavailable": unavailable,
        }
    )
