"""POST /v1/identify: a vibration mode (Omega, sigma) from a recorded free vibration, and the tuned smoother.

The identification fits a damped sinusoid by least squares instead of reading two peaks (Biagiotti
eq. 16, still reported for comparison).
"""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Body

from app import problems
from app.deps import SettingsDep
from app.examples import OMEGA_RAD_S, SIGMA_1_S
from app.responses import NumpyJSONResponse
from app.schemas.simulate import check_sample_count
from app.schemas.smoothers import IdentifyRequest, IdentifyResponse
from app.settings import Settings
from models.errors import InvalidParameter
from models.plants import FREQUENCY_MAX_HZ, FREQUENCY_MIN_HZ
from optim.smoothers import identify, tuned_duration_s, vibration_free_durations_s

router = APIRouter(prefix="/v1", tags=["smoothers"])


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
    settings: SettingsDep,
) -> NumpyJSONResponse:
    """Fit A e^(sigma t) cos(Omega t + phi) + offset to the record by least squares (Sec. V-A asks for
    the period T0 and the decay sigma, eq. 16, read from two peaks; the fit uses every sample and reports
    its quality). Records with fewer than 2 periods, fewer than 4 samples per period or no oscillation
    clearly above the noise are refused (422, field ``signal`` or ``time_s``)."""
    return NumpyJSONResponse(identify_respond(request, settings))
