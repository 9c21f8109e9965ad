"""Trajectory smoothers (Biagiotti, Melchiorri and Moriello 2020): POST /v1/profiles/smoother and
POST /v1/identify.

``respond`` and ``identify_respond`` build the full response bodies without HTTP; ``respond_async`` is
``respond`` with the signature of /v1/compare's runners.

Where the service departs from the paper: vibration-free durations of the (damped) harmonic smoother
are odd multiples (2m+1) pi/Omega, m >= 1 (eqs. 13 and 15 also allow even multiples, which leave a
clear residual); eq. (17)'s rounding N = round(T/Ts) is reported with the residual it leaves and the
sample period that avoids it; the identification fits a damped sinusoid by least squares instead of
reading two peaks (eq. 16, still reported for comparison).
"""

from __future__ import annotations

import math
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Body, Depends, Request
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from app import problems
from app.responses import CSV_RESPONSE_DOC, CsvFormat, NumpyJSONResponse, negotiate
from app.schemas.family import family_response, sample_count_check
from app.schemas.plants import mode_out, to_plant
from app.schemas.simulate import check_sample_count
from app.schemas.smoothers import IdentifyRequest, IdentifyResponse, SmootherRequest, SmootherResponse
from app.settings import Settings, get_settings
from models.errors import InvalidParameter
from models.plants import FREQUENCY_MAX_HZ, FREQUENCY_MIN_HZ, Plant
from models.smoothers import MAX_RATE_TIMES_PERIOD, Chain, refinement, step_response
from optim.smoothers import (
    ChainDesign,
    DiscreteDesign,
    FilterSpec,
    cancels,
    chain_residual,
    commensurate_sample_period_s,
    design_chain,
    design_discrete,
    hold_residual,
    identify,
    same_time_ratio,
    tuned_duration_s,
    vibration_free_durations_s,
)

router = APIRouter(prefix="/v1", tags=["smoothers"])

# --- worked examples: the paper's identified plant (Sec. VI) -------------------------------

SIGMA_1_S = -15.6539  # identified decay (the paper's sigma)
OMEGA_RAD_S = 122.7185  # identified damped frequency
_OMEGA_N = math.hypot(SIGMA_1_S, OMEGA_RAD_S)
BIAGIOTTI_PLANT: dict[str, Any] = {
    "kind": "mode",
    "natural_frequency_hz": round(_OMEGA_N / (2 * math.pi), 10),  # 19.6895151859 Hz
    "damping_ratio": round(-SIGMA_1_S / _OMEGA_N, 10),  # 0.1265341244
}
_T0 = 2 * math.pi / OMEGA_RAD_S  # 0.0512 s

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
            "filters": [{"type": "exponential"}, {"type": "exponential", "duration_s": round(_T0 / 2, 10)}],
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


def _synthetic_record() -> dict[str, list[float]]:
    """0.3 s of the identified mode's free vibration at 1 kHz: 4 N e^(sigma t) cos(Omega t) + 0.5 N."""
    t = np.arange(301) * 1e-3
    y = 4.0 * np.exp(SIGMA_1_S * t) * np.cos(OMEGA_RAD_S * t) + 0.5
    return {"time_s": [round(float(v), 6) for v in t], "signal": [round(float(v), 6) for v in y]}


IDENTIFY_EXAMPLES: dict[str, dict[str, Any]] = {
    "biagiotti_free_vibration": {
        "summary": "Sec. V-A / VI: a free vibration of the identified plant",
        "description": "A synthesised spring-force record of the Sec. VI plant (sigma = -15.6539 1/s, "
        "Omega = 122.7185 rad/s) over 0.3 s at 1 kHz; the fit returns them and the tuned smoother T = 0.0768 s.",
        "value": _synthetic_record(),
    }
}


# --- /v1/profiles/smoother ------------------------------------------------------------------


def _filters_out(design: ChainDesign) -> list[dict[str, Any]]:
    out = []
    mode = design.mode
    for f, role in zip(design.chain.filters, design.roles, strict=True):
        prv = None
        if mode is not None:
            ratio = same_time_ratio(Chain((f,)), mode)
            prv = 100.0 * ratio if math.isfinite(ratio) else None
        out.append(
            {
                "type": f.kind,
                "duration_s": f.duration_s,
                "decay_rate_1_s": f.decay_rate_1_s,
                "role": role,
                "vibration_free": None if mode is None else cancels(f, mode),
                "percent_residual_vibration": prv,
                "vibration_free_durations_s": [] if mode is None else vibration_free_durations_s(f.kind, mode),
            }
        )
    return out


def _discrete_out(d: DiscreteDesign) -> dict[str, Any]:
    return {
        "sample_period_s": d.sample_period_s,
        "filters": [
            {
                "type": f.kind,
                "samples": f.samples,
                "duration_s": f.duration_s,
                "numerator": f.numerator,
                "denominator": f.denominator,
                "gain": f.gain,
            }
            for f in d.filters
        ],
        "lead_s": d.lead_s,
        "max_deviation": d.max_deviation,
        "percent_residual_vibration": d.percent_residual_vibration,
        "residual_amplitude": d.residual_amplitude,
        "residual_fraction_of_move": d.residual_fraction_of_move,
        "exact_sample_period_s": d.exact_sample_period_s,
        "samples": d.samples,
    }


def respond(request: SmootherRequest, settings: Settings) -> dict[str, Any]:
    """The full response body of POST /v1/profiles/smoother."""
    plant = to_plant(request.plant)
    if request.limits.max_torque_nm is not None:
        raise InvalidParameter(
            "limits.max_torque_nm",
            request.limits.max_torque_nm,
            "the smoother family designs for velocity, acceleration and jerk limits; the torque is reported in "
            "metrics.peak_motor_torque_nm",
        )
    if request.sensitivity is not None and not plant.modes():
        raise InvalidParameter("sensitivity", "requested", "the plant has no vibration mode to evaluate it around")
    h = request.displacement
    specs = [FilterSpec(f.type, f.duration_s) for f in request.filters]
    design = design_chain(plant, h, specs, request.core_limits())
    chain = design.chain
    warnings = list(design.warnings)
    k = refinement(chain, request.sample_period_s)
    period = request.sample_period_s / k
    if k == 1:
        sample_count_check(chain.total_duration_s, period, settings.max_samples)
    else:
        count = int(chain.total_duration_s / period) + 1
        if count > settings.max_samples:
            raise InvalidParameter(
                "sample_period_s",
                request.sample_period_s,
                f"the filters (|lambda| = {chain.fastest_rate_1_s:.6g} 1/s) need samples at most {period:.3g} s apart to "
                f"be described exactly, and {count} samples over {chain.total_duration_s:.6g} s exceed the cap of "
                f"{settings.max_samples}",
            )
        warnings.append(
            f"sample_period_s {request.sample_period_s:.6g} s is divided by {k} (1 sample in {k} lies on the requested "
            f"grid): between samples the profile is exact only for |lambda| Ts <= {MAX_RATE_TIMES_PERIOD:g} "
            f"(|lambda| = {chain.fastest_rate_1_s:.6g} 1/s here)"
        )
    response = step_response(chain, h, period)
    if response.time_s.size > settings.max_samples:
        raise InvalidParameter(
            "sample_period_s",
            request.sample_period_s,
            f"{response.time_s.size} samples (with the filters' breakpoints) exceed the cap of {settings.max_samples}",
        )
    residual = chain_residual(chain, plant, h, design.mode)
    discrete = None
    if request.discrete_sample_period_s is not None:
        discrete = design_discrete(chain, plant, h, design.mode, request.discrete_sample_period_s, settings.max_samples)
    mode = design.mode
    if mode is not None and not residual.vibration_free:
        free = vibration_free_durations_s("damped_harmonic", mode)
        warnings.append(
            f"the chain does not cancel the plant's first mode ({mode.natural_frequency_hz:.6g} Hz, zeta "
            f"{mode.damping_ratio:.4g}): {100 * residual.fraction_of_move:.3g} % of the move is left; a damped_harmonic "
            f"filter of {', '.join(f'{t:.6g}' for t in free)} s (or omit duration_s) cancels it"
        )
    if (
        discrete is not None
        and discrete.percent_residual_vibration is not None
        and discrete.percent_residual_vibration > 1e-4
    ) and discrete.exact_sample_period_s is not None:
        warnings.append(
            f"at Ts = {discrete.sample_period_s:.6g} s the discrete filters round T/Ts, which leaves "
            f"{discrete.percent_residual_vibration:.3g} % of the unfiltered vibration; Ts = "
            f"{discrete.exact_sample_period_s:.9g} s makes N Ts = T exactly"
        )
    design_body = {
        "filters": _filters_out(design),
        "total_duration_s": chain.total_duration_s,
        "continuous_derivatives": chain.continuous_derivatives,
        "mode": None if mode is None else mode_out(mode).model_dump(),
        "vibration_free": residual.vibration_free,
        "percent_residual_vibration": residual.percent_residual_vibration,
        "residual_amplitude_closed_form": residual.amplitude,
        "residual_fraction_of_move": residual.fraction_of_move,
        "sample_period_s": period,
        "commensurate_sample_period_s": commensurate_sample_period_s(chain, mode, request.sample_period_s),
        "hold_residual_fraction_of_move": hold_residual(response, plant),
        "predicted_peaks": dict(zip(("velocity", "acceleration", "jerk"), design.predicted_peaks, strict=True)),
        "discrete": None if discrete is None else _discrete_out(discrete),
    }
    command = response.command()
    horizon = _horizon(request, plant, chain.total_duration_s)
    if horizon > command.time_s[-1]:
        sample_count_check(horizon, period, settings.max_samples, "horizon_s")
        command = command.resampled(period, end_s=horizon)  # the motor rests at h; the load rings, or not
    body, result = family_response(
        plant, command, design_body, sensitivity_request=request.sensitivity, warnings=warnings
    )
    bounds = request.core_limits().by_order()
    measured = (result.peak_velocity, result.peak_acceleration, result.peak_jerk)
    for name, bound, peak in zip(("velocity", "acceleration", "jerk"), bounds, measured, strict=True):
        if bound is None:
            continue
        if peak is None:
            body["warnings"].append(f"limits.max_{name} is set but the profile's {name} is impulsive")
        elif peak > bound * (1 + 1e-9):
            body["warnings"].append(f"limits.max_{name} is exceeded by the profile: peak {peak:.9g} > {bound:.9g}")
    return body


def _horizon(request: SmootherRequest, plant: Plant, end_s: float) -> float:
    if request.horizon_s is not None:
        if request.horizon_s < end_s:
            raise InvalidParameter(
                "horizon_s", request.horizon_s, f"must be >= the filters' total duration ({end_s:.6g} s)"
            )
        return request.horizon_s
    modes = plant.modes()
    return end_s + (5.0 * modes[0].natural_period_s if modes else 0.0)


async def respond_async(request: SmootherRequest, settings: Settings, pool: Any = None) -> dict[str, Any]:
    """``respond`` in the thread pool, with the signature of /v1/compare's runners (no solver is used)."""
    return await run_in_threadpool(respond, request, settings)


@router.post(
    "/profiles/smoother",
    summary="Smoother chain (rectangular, harmonic, damped harmonic, exponential filters) for a rest-to-rest move",
    response_model=SmootherResponse,
    responses={**CSV_RESPONSE_DOC, **problems.responses(413, 422)},
)
def smoother_profile(
    request: Annotated[SmootherRequest, Body(openapi_examples=SMOOTHER_EXAMPLES)],
    http: Request,
    settings: Annotated[Settings, Depends(get_settings)],
    format: CsvFormat = None,
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
    return negotiate(http, respond(request, settings), "smoother profile")


# --- /v1/identify ----------------------------------------------------------------------------


def identify_respond(request: IdentifyRequest, settings: Settings) -> dict[str, Any]:
    """The full response body of POST /v1/identify."""
    check_sample_count("time_s", len(request.time_s), settings.max_samples)
    result = identify(np.asarray(request.time_s, dtype=float), np.asarray(request.signal, dtype=float))
    mode = result.mode
    if not FREQUENCY_MIN_HZ <= mode.natural_frequency_hz <= FREQUENCY_MAX_HZ:
        raise InvalidParameter(
            "time_s",
            f"{len(request.time_s)} samples",
            f"the identified natural frequency {mode.natural_frequency_hz:.6g} Hz lies outside "
            f"[{FREQUENCY_MIN_HZ:g}, {FREQUENCY_MAX_HZ:g}] Hz (are the times in seconds?)",
        )
    two_peak = None
    if result.two_peak is not None:
        two_peak = {"damped_angular_frequency_rad_s": result.two_peak[0], "decay_rate_1_s": result.two_peak[1]}
    return {
        "damped_angular_frequency_rad_s": result.damped_angular_frequency_rad_s,
        "decay_rate_1_s": result.decay_rate_1_s,
        "natural_frequency_rad_s": mode.natural_frequency_rad_s,
        "natural_frequency_hz": mode.natural_frequency_hz,
        "damping_ratio": mode.damping_ratio,
        "damped_period_s": mode.damped_period_s,
        "fit": {
            "r_squared": result.r_squared,
            "rms_residual": result.rms_residual,
            "amplitude": result.amplitude,
            "offset": result.offset,
            "periods": result.periods,
            "signal_to_noise": result.signal_to_noise,
            "damped_angular_frequency_std_rad_s": result.frequency_std_rad_s,
            "decay_rate_std_1_s": result.decay_rate_std_1_s,
            "samples": result.samples,
        },
        "two_peak_estimate": two_peak,
        "smoother": {
            "type": "damped_harmonic",
            "duration_s": tuned_duration_s("damped_harmonic", mode),
            "decay_rate_1_s": mode.decay_rate_1_s,
            "vibration_free_durations_s": vibration_free_durations_s("damped_harmonic", mode),
        },
        "plant": {
            "kind": "mode",
            "natural_frequency_hz": mode.natural_frequency_hz,
            "damping_ratio": mode.damping_ratio,
        },
        "warnings": list(result.warnings),
    }


@router.post(
    "/identify",
    summary="Identify a vibration mode (Omega, sigma) from a free-vibration record and tune the smoother",
    response_model=IdentifyResponse,
    responses=problems.responses(413, 422),
)
def identify_mode(
    request: Annotated[IdentifyRequest, Body(openapi_examples=IDENTIFY_EXAMPLES)],
    settings: Annotated[Settings, Depends(get_settings)],
) -> NumpyJSONResponse:
    """Fit A e^(sigma t) cos(Omega t + phi) + offset to the record by least squares (Sec. V-A asks for
    the period T0 and the decay sigma, eq. 16, read from two peaks; the fit uses every sample and reports
    its quality). Records with fewer than 2 periods, fewer than 4 samples per period or no oscillation
    clearly above the noise are refused (422, field ``signal`` or ``time_s``)."""
    return NumpyJSONResponse(identify_respond(request, settings))
