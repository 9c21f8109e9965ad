"""POST /v1/profiles/stap: symmetric trapezoidal acceleration profiles (Cusimano 2022)."""

from __future__ import annotations

import math
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Body, Depends, Request, Response
from starlette.concurrency import run_in_threadpool

from app import problems
from app.examples import CUSIMANO_8HZ, CUSIMANO_40HZ
from app.responses import CSV_RESPONSE_DOC, CsvFormat, negotiate
from app.schemas.family import family_response, sample_count_check
from app.schemas.plants import to_plant
from app.schemas.stap import AUTO_RULE, StapIn, StapOut
from app.settings import Settings, get_settings
from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.plants import Plant
from models.sensitivity import band_below, sensitivity
from models.stap import Stap, load_acceleration_oscillation, stap_sensitivity
from optim import stap as synthesis
from optim.solver import SolveCaps
from optim.workers import WARMUPS, SolverPool

router = APIRouter(prefix="/v1", tags=["stap"])
WARMUPS.append(synthesis.warm_up)

DEFAULT_SAMPLES = 2000
TAIL_PERIODS = 5.0
CUSIMANO_8HZ_LIGHT_LOAD: dict[str, Any] = {
    "kind": "two_inertia",
    "motor_inertia_kgm2": 0.005,
    "load_inertia_kgm2": 0.00125,
    "stiffness_nm_per_rad": 3.158273408,  # J_L (2 pi 8 Hz)^2 with J_L = J_M/4
    "damping_nms_per_rad": 0.0,
}
_SEC3 = {"plant": CUSIMANO_40HZ, "target_velocity": 150.0, "max_acceleration": 1000.0}

EXAMPLES: dict[str, dict[str, Any]] = {
    "section_3_k1": {
        "summary": "Sec. 3 (Fig. 14): 150 rad/s on a 40 Hz mode, a_Max = 1000 rad/s^2, k_j = 1",
        "description": "t_a,min = 0.15 s (eq. 21), t_j = 1/f_n,e = 0.025 s (eq. 50), t_a = 0.175 s (eq. 61): no residual.",
        "value": {**_SEC3, "jerk_periods": 1, "sensitivity": {"min_ratio": 0.5, "max_ratio": 1.5, "count": 201}},
    },
    "section_3_k3": {
        "summary": "Sec. 3 (Fig. 16): the same with k_j = 3 (t_j = 0.075 s, t_a = 0.225 s)",
        "value": {**_SEC3, "jerk_periods": 3},
    },
    "fig_17_side_band": {
        "summary": "Fig. 17: t_a = 0.165 s with the side band (k_j, delta) = (0, 1): t_j = dec(f_n,e t_a)/f_n,e = 0.015 s",
        "description": "Zero residual at f_n,e, but the load acceleration oscillates during t_c and the SC is poor "
        "(Appendix C: f_n,e t_a,min = 6 is whole and 0.15 <= t_a < 0.175).",
        "value": {**_SEC3, "acceleration_time_s": 0.165, "jerk_periods": 0, "delta": 1},
    },
    "table_2_torque_limit": {
        "summary": "Sec. 3: Table 2 motor (10 N m) with J_L = J_M at 8 Hz; the limit lowered for 0.9 f_n,e",
        "description": "a_Max = 10/(J_M + J_L) = 1000 rad/s^2 (eq. 19), t_a,min = 0.15 s; the torque oscillates by about "
        "0.055 M at 0.9 f_n,e (eqs. 57-59), so the limit is lowered to 0.948 of it (the paper's 0.94).",
        "value": {"plant": CUSIMANO_8HZ, "target_velocity": 150.0, "max_torque_nm": 10.0, "jerk_periods": 1},
    },
    "table_2_light_load": {
        "summary": "Sec. 3: the same motor with J_L = J_M/4: a triangle peaking at 1200 rad/s^2 (eq. 31)",
        "value": {"plant": CUSIMANO_8HZ_LIGHT_LOAD, "target_velocity": 150.0, "max_torque_nm": 10.0, "jerk_periods": 1},
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
        "value": {**_SEC3, "displacement": 30.0, "jerk_periods": 1},
    },
}


def core_request(request: StapIn, plant: Plant, settings: Settings) -> synthesis.StapRequest:
    if request.target_velocity is None and request.displacement is None:
        raise InvalidParameter(
            "target_velocity", None, "give target_velocity (rest-to-velocity) or displacement (rest-to-rest)"
        )
    if request.optimization is not None and request.method != "optimized":
        raise InvalidParameter("optimization", "given", "applies to method 'optimized' only")
    options = request.optimization
    return synthesis.check_request(
        synthesis.StapRequest(
            plant=plant,
            target_velocity=request.target_velocity,
            displacement=request.displacement,
            max_acceleration=request.max_acceleration,
            max_torque_nm=request.max_torque_nm,
            jerk_periods=None if request.jerk_periods == "auto" else int(request.jerk_periods),
            delta=request.delta,
            acceleration_time_s=request.acceleration_time_s,
            frequency_uncertainty=request.frequency_uncertainty,
            residual_tolerance=request.residual_tolerance,
            objective=options.objective if options else "residual",
            band_damping_ratios=tuple(options.damping_ratios) if options and options.damping_ratios else None,
            frequency_points=options.frequency_points if options else 21,
            caps=SolveCaps(settings.solve_max_iterations, settings.solve_time_limit_s),
        )
    )


def _command(stap: Stap, move: Any) -> PiecewiseCommand:
    return stap.command() if move is None else move.command()


def _horizon(request: StapIn, plant: Plant, end_s: float) -> float:
    if request.horizon_s is None:
        return end_s + TAIL_PERIODS * plant.modes()[0].natural_period_s
    if request.horizon_s < end_s:
        raise InvalidParameter("horizon_s", request.horizon_s, f"must be >= the command's end ({end_s:.6g} s)")
    return request.horizon_s


def _sampled(command: PiecewiseCommand, request: StapIn, horizon: float, max_samples: int) -> PiecewiseCommand:
    """The command on a uniform grid with its corners kept (the samples describe it exactly)."""
    corners = command.time_s.size
    default = horizon / max(1, min(DEFAULT_SAMPLES, max_samples - corners - 2))
    period = request.sample_period_s if request.sample_period_s is not None else default
    sample_count_check(horizon, period, max_samples - corners)
    return command.resampled(period, end_s=horizon)


def _sensitivity(
    request: StapIn, plant: Plant, command: PiecewiseCommand, stap: Stap, rest_to_rest: bool, max_samples: int
) -> dict[str, Any]:
    """Residual / move versus f_n/f_n,e: Appendix B where zeta = 0 (rest-to-velocity), else the exact free state."""
    asked = request.sensitivity
    assert asked is not None
    mode = plant.modes()[0]
    zetas = np.asarray(asked.damping_ratios or [mode.damping_ratio], dtype=float)
    if asked.points * zetas.size > max_samples:
        field = "sensitivity.frequency_ratios" if asked.frequency_ratios is not None else "sensitivity.count"
        raise InvalidParameter(field, asked.points * zetas.size, f"at most {max_samples} (frequency, damping) points")
    ratios = asked.ratios()
    exact = sensitivity(command, mode.natural_frequency_rad_s, ratios, zetas)
    closed = (zetas == 0.0) & (not rest_to_rest)
    grid = exact.residual.copy()
    if np.any(closed):
        grid[closed] = stap_sensitivity(stap, mode.natural_frequency_hz, ratios)
    band = band_below(ratios, grid[0], 0.05)
    return {
        "frequency_ratio": ratios,
        "residual_vibration": grid[0],
        "quantity": exact.quantity,
        "damping_ratio": zetas,
        "residual_vibration_grid": grid if zetas.size > 1 else None,
        "band_5_percent": list(band) if band else None,
        "method": ["appendix_b" if c else "free_state" for c in closed],
    }


def _design_out(
    request: StapIn,
    closed: synthesis.StapDesign,
    optimized: synthesis.OptimizedDesign | None,
    residual: float,
) -> dict[str, Any]:
    stap = closed.stap if optimized is None else optimized.stap
    move = closed.move if optimized is None else optimized.move
    f = closed.estimated_frequency_hz
    speed = abs(stap.velocity)
    if optimized is None:
        a_max, rule, torque = closed.acceleration_limit, closed.rule, closed.torque
        k_j, delta = closed.k_j, closed.delta
    else:
        a_max, torque = request.max_acceleration, None
        k_j = delta = None
        rule = f"optimized ({optimized.objective}): IPOPT over (t_a, t_j) from the closed-form design ({closed.rule})"
    torque_out = None
    if torque is not None:
        torque_out = {
            "max_torque_nm": torque.max_torque_nm,
            "nodal_acceleration_limit": torque.nodal_acceleration_limit,
            "nodal_min_acceleration_time_s": speed / torque.nodal_acceleration_limit,
            "inertia_ratio": torque.inertia_ratio,
            "coefficient": torque.coefficient,
            "load_acceleration_oscillation": torque.load_acceleration_oscillation,
            "torque_overshoot": torque.torque_overshoot,
            "worst_frequency_ratio": torque.worst_frequency_ratio,
            "factor": torque.factor,
            "acceleration_limit": torque.acceleration_limit,
        }
    peak = abs(stap.peak_acceleration)
    out: dict[str, Any] = {
        "method": request.method,
        "move": "rest_to_velocity" if move is None else "rest_to_rest",
        "rule": rule,
        "auto_rule": AUTO_RULE,
        "estimated_frequency_hz": f,
        "target_velocity": stap.velocity,
        "acceleration_time_s": stap.acceleration_time_s,
        "jerk_time_s": stap.jerk_time_s,
        "constant_acceleration_time_s": stap.constant_acceleration_time_s,
        "min_acceleration_time_s": None if a_max is None else speed / a_max,
        "peak_acceleration": peak,
        "peak_jerk": None if stap.jerk is None else abs(stap.jerk),
        "shape": stap.shape,
        "k_j": k_j,
        "delta": delta,
        "jerk_periods": f * stap.jerk_time_s,
        "acceleration_time_periods": f * stap.acceleration_time_s,
        "dimensionless_jerk_time": stap.dimensionless_jerk_time,
        "acceleration_limit": a_max,
        "limit_reached": a_max is not None and abs(peak - a_max) <= synthesis.LIMIT_RTOL * a_max,
        "torque_limit": torque_out,
        "load_acceleration_oscillation": float(load_acceleration_oscillation(1.0, f * stap.jerk_time_s)),
        "frequency_uncertainty": request.frequency_uncertainty,
        "residual_tolerance": request.residual_tolerance,
        "band_worst_residual": synthesis.band_worst(stap, f, request.frequency_uncertainty),
        "candidates": [vars(c) for c in closed.candidates]
        if closed.fixed_acceleration_time and optimized is None
        else None,
        "candidates_truncated": closed.candidates_truncated
        if closed.fixed_acceleration_time and optimized is None
        else None,
        "k_j_max": closed.k_j_max if optimized is None else None,
        "delta_f": closed.delta_f if optimized is None else None,
        "paper_k_j_max": closed.paper_k_j_max if optimized is None else None,
        "paper_delta_f": closed.paper_delta_f if optimized is None else None,
        "auto_steps": [vars(s) for s in closed.auto_steps] or None,
        "displacement": None if move is None else move.displacement,
        "cruise_velocity": None if move is None else move.ramp.velocity,
        "cruise_time_s": None if move is None else move.cruise_time_s,
        "total_time_s": stap.acceleration_time_s if move is None else move.total_time_s,
        "requested_velocity": None if move is None else closed.requested_velocity,
        "velocity_lowered": None if move is None else closed.velocity_lowered,
        "residual_vibration": residual,
        "optimization": None,
    }
    if optimized is not None:
        out["optimization"] = {
            "objective": optimized.objective,
            "selection": optimized.selection,
            "nominal_residual": optimized.nominal_residual,
            "grid_worst_residual": optimized.grid_worst_residual,
            "closed_form": {
                "acceleration_time_s": optimized.start.acceleration_time_s,
                "jerk_time_s": optimized.start.jerk_time_s,
                "nominal_residual": optimized.start_nominal_residual,
                "grid_worst_residual": optimized.start_grid_worst_residual,
            },
            "acceleration_time_bounds_s": list(optimized.acceleration_time_bounds_s),
            "jerk_time_floor_s": optimized.jerk_time_floor_s,
            "torque_constrained": request.max_torque_nm is not None,
            "solver": {
                "status": optimized.solver.status,
                "iterations": optimized.solver.iterations,
                "solve_time_s": optimized.solver.solve_time_s,
                "solves": optimized.solves,
            },
        }
    return out


def compose(
    request: StapIn,
    plant: Plant,
    closed: synthesis.StapDesign,
    optimized: synthesis.OptimizedDesign | None,
    settings: Settings,
) -> dict[str, Any]:
    """The response body for a finished design: samples, simulation, metrics, sensitivity (CPU work)."""
    stap = closed.stap if optimized is None else optimized.stap
    move = closed.move if optimized is None else optimized.move
    exact = _command(stap, move)
    end = float(exact.time_s[-1])
    horizon = _horizon(request, plant, end)
    command = _sampled(exact, request, horizon, settings.max_samples)
    warnings = list(closed.notes if optimized is None else ()) + list(closed.move_notes)
    body, result = family_response(plant, command, {}, settling_tolerance=request.settling_tolerance)
    body["warnings"] = warnings
    scale = plant.load_move(stap.velocity if move is None else move.displacement)  # the load's move
    amplitude = result.residual_velocity_amplitude if move is None else result.residual_amplitude
    residual = amplitude / scale
    body["design"] = _design_out(request, closed, optimized, residual)
    if request.sensitivity is not None:
        body["sensitivity"] = _sensitivity(request, plant, exact, stap, move is not None, settings.max_samples)
    mode = plant.modes()[0]
    if optimized is None and mode.damping_ratio > 0.0 and residual > 1e-6:
        warnings.append(
            f"the closed-form rules assume zeta = 0 (Sec. 2.3); with this plant's zeta = {mode.damping_ratio:.3g} the design "
            f"leaves {100 * residual:.3g} % of the move as residual vibration (method 'optimized' minimises it)"
        )
    if len(plant.modes()) > 1:
        warnings.append(
            f"the STAP is designed for the first mode ({mode.natural_frequency_hz:.6g} Hz); the other modes' residuals are in "
            "metrics.modes"
        )
    if request.max_torque_nm is not None and result.peak_motor_torque_nm is not None:
        if result.peak_motor_torque_nm > request.max_torque_nm * (1.0 + 1e-6):
            warnings.append(
                f"the simulated motor torque peaks at {result.peak_motor_torque_nm:.6g} N m, above max_torque_nm = "
                f"{request.max_torque_nm:.6g}"
            )
    peak = result.peak_acceleration
    if request.max_acceleration is not None and peak is not None and peak > request.max_acceleration * (1.0 + 1e-9):
        warnings.append(
            f"the acceleration peaks at {peak:.6g}, above max_acceleration = {request.max_acceleration:.6g}"
        )
    for name, values in (("profile", body["profile"]), ("load", body["load"])):
        for key, array in values.items():
            if array is not None and not np.all(np.isfinite(np.asarray(array, dtype=float))):
                raise InvalidParameter(
                    "target_velocity", "out of range", f"the {name}.{key} overflows double precision"
                )
    if not math.isfinite(residual):
        raise InvalidParameter("target_velocity", "out of range", "the residual overflows double precision")
    return body


async def respond(request: StapIn, settings: Settings, pool: SolverPool) -> dict[str, Any]:
    """The full response body (used by the route and by /v1/compare)."""
    plant = to_plant(request.plant)
    core = core_request(request, plant, settings)
    closed = await run_in_threadpool(synthesis.design, core)
    # Refuse a sampling above the cap before any solve (the optimised command ends near this one).
    end = float(_command(closed.stap, closed.move).time_s[-1])
    horizon = (
        request.horizon_s if request.horizon_s is not None else end + TAIL_PERIODS * plant.modes()[0].natural_period_s
    )
    if request.sample_period_s is not None:
        sample_count_check(horizon, request.sample_period_s, settings.max_samples)
    optimized = None
    if request.method == "optimized":
        deadline = 4.0 * settings.solve_time_limit_s + settings.solve_grace_s
        optimized = await pool.run(synthesis.optimize, core, closed, deadline_s=deadline)
    return await run_in_threadpool(compose, request, plant, closed, optimized, settings)


@router.post(
    "/profiles/stap",
    summary="Symmetric trapezoidal acceleration profile without residual vibration (Cusimano)",
    response_model=StapOut,
    responses={**CSV_RESPONSE_DOC, **problems.responses(413, 422, 503, 504)},
)
async def stap_profile(
    body: Annotated[StapIn, Body(openapi_examples=EXAMPLES)],
    request: Request,
    settings: Annotated[Settings, Depends(get_settings)],
    format: CsvFormat = None,
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
    return negotiate(request, await respond(body, settings, request.app.state.pool), "STAP profile")
