"""POST /v1/identify: vibration modes from a measured record, and a design for them.

A JSON body (``time_s``, ``signal``) is the original form: a free vibration fitted with one damped
sinusoid (Biagiotti eq. 16, the two-peak estimate still reported for comparison) and the tuned smoother.
A ``text/csv`` body is a measured record (a time column and one or more signal columns, e.g. an
accelerometer's x, y, z; optionally the known command): its Welch spectrum, peaks and a sum of damped
sinusoids fitted per mode with 95 % intervals (optim.modal), the record's quality, and with a move and
limits in the query the fastest design whose 5 % band covers the lowest mode's interval (optim.recommend),
each candidate run through the family endpoints' pipeline (app.profiles.profile.profile).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Body, Query, Request
from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples import OMEGA_RAD_S, SIGMA_1_S
from app.responses import NumpyJSONResponse
from app.schemas.family import ProfileRequest
from app.schemas.identify import IdentifyMeasurementResponse, MeasurementParams
from app.schemas.registry import REQUEST_SCHEMAS
from app.schemas.simulate import check_sample_count
from app.schemas.smoothers import IdentifyRequest, IdentifyResponse
from app.services import profile as profiles
from app.settings import Settings
from models.errors import InvalidParameter
from models.plants import FREQUENCY_MAX_HZ, FREQUENCY_MIN_HZ
from optim.family import FAMILIES
from optim.modal import CONFIDENCE, ModalIdentification, identify_modes
from optim.recommend import Move, MoveLimits, RunOne, plant_interval, recommend, recommendation_candidates
from optim.record_csv import parse_record_csv
from optim.smoothers import identify, tuned_duration_s, vibration_free_durations_s
from optim.workers import Executor, InlineExecutor

router = APIRouter(prefix="/v1", tags=["smoothers"], route_class=problems.JSONRoute)

CSV_MEDIA_TYPE = "text/csv"


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


# --- the measured record (text/csv) ---------------------------------------------------------------------


def parse_family_request(family: str, body: Mapping[str, Any]) -> ProfileRequest:
    """A recommended request parsed by its endpoint's schema (an InvalidParameter naming the field if not)."""
    try:
        return REQUEST_SCHEMAS[family].model_validate(body)
    except ValidationError as exc:
        err = exc.errors()[0]
        raise InvalidParameter(problems.field_path(tuple(err["loc"])), None, str(err["msg"])) from None


def runner(settings: Settings, executor: Executor, threads: Executor = profiles.INLINE) -> RunOne:
    """A ``run_one``: each candidate through the family endpoints' service layer (app.profiles.profile.profile) on
    ``executor`` and ``threads``: the route's solver pool and design threads, or in-process."""

    async def run_one(family: str, body: dict[str, Any]) -> dict[str, Any]:
        request = parse_family_request(family, body)
        return await profiles.profile(FAMILIES[family], request, settings, executor, threads)

    return run_one


def in_process_runner(settings: Settings) -> RunOne:
    """A ``run_one`` without a server or a solver pool (for the CLI): the candidates run in this process, the
    solver ones one after the other (IPOPT is not thread-safe)."""
    return runner(settings, InlineExecutor())


def _mode_dict(mode: Any) -> dict[str, Any]:
    return dict(mode.as_dict())


def _measurement_body(result: ModalIdentification, samples: int) -> dict[str, Any]:
    spectrum = result.spectrum
    return {
        "modes": [_mode_dict(m) for m in result.modes],
        "spectrum": {
            "frequency_hz": spectrum.frequency_hz,
            "psd": spectrum.psd,
            "resolution_hz": spectrum.resolution_hz,
            "segment_samples": spectrum.segment_samples,
            "window": "boxcar",
        },
        "quality": {
            "sample_rate_hz": result.sample_rate_hz,
            "nyquist_hz": result.sample_rate_hz / 2.0,
            "samples": samples,
            "signals": list(result.names),
            "fit_start_s": result.window_start_s,
            "fit_start_source": result.window_source,
            "fit_samples": result.window_samples,
            "r_squared": result.r_squared,
            "noise_rms": list(result.noise_rms),
            "offsets": list(result.offsets),
            "degrees_of_freedom": result.degrees_of_freedom,
            "confidence": CONFIDENCE,
            "t_quantile": result.t_quantile,
            "alias_energy_fraction": result.alias_energy_fraction,
            "resampled": result.resampled,
        },
        "warnings": list(result.warnings),
    }


def identify_record_csv(text: str, params: MeasurementParams, max_rows: int) -> tuple[ModalIdentification, int]:
    """Parse and fit a CSV record (pure: no I/O); the identification and the record's sample count."""
    record = parse_record_csv(text, max_rows=max_rows, command_column=params.command_column)
    return identify_modes(record, max_modes=params.max_modes, start_s=params.start_s), int(record.time_s.size)


async def identify_csv(
    text: str,
    params: MeasurementParams,
    run_one: RunOne | None,
    *,
    max_rows: int,
    threads: Executor = profiles.INLINE,
    deadline_s: float = 0.0,
) -> dict[str, Any]:
    """The whole answer of POST /v1/identify for a CSV record, with candidates run by ``run_one(family, request)``
    (returns the endpoint's response body or raises a DomainError). The HTTP route runs them through
    app.profiles.profile.profile; a caller without a server (the CLI) passes its own runner, or None for no
    recommendation."""
    params.check()
    # the fit, in the route's design threads (optim.threads: bounded admission, deadline_s), or in-process
    result, samples = await threads.run(identify_record_csv, text, params, max_rows, deadline_s=deadline_s)
    body = _measurement_body(result, samples)
    mode, interval = plant_interval(result.modes)
    plant = {"kind": "mode", "natural_frequency_hz": mode.natural_frequency_hz, "damping_ratio": mode.damping_ratio}
    recommendation: dict[str, Any] = {
        "plant": plant,
        "frequency_ratio_interval": list(interval),
        "reason": "",
        "candidates": [],
    }
    body["recommended"] = None
    body["recommendation"] = recommendation
    if not params.has_move():
        recommendation["reason"] = (
            "no move given: add displacement or target_velocity (and max_velocity, max_acceleration, max_jerk) "
            "as query parameters for a recommended design"
        )
        return body
    if run_one is None:
        recommendation["reason"] = "no runner given: the candidates were not run"
        return body
    move = Move(params.displacement, params.target_velocity)
    limits = MoveLimits(params.max_velocity, params.max_acceleration, params.max_jerk)
    candidates = recommendation_candidates(result.modes, move, limits)
    chosen, outcomes = await recommend(candidates, run_one, interval)
    recommendation["candidates"] = outcomes
    if chosen is None:
        recommendation["reason"] = (
            "no candidate's 5 % band covers the interval within these limits (see candidates[].reason)"
        )
        return body
    best = next(o for o, c in zip(outcomes, candidates, strict=True) if c is chosen)
    body["recommended"] = {
        "endpoint": chosen.endpoint,
        "request": chosen.request,
        "family": chosen.family,
        "label": best["label"],
        "settling_time_s": best["settling_time_s"],
        "band_5_percent": best["band_5_percent"],
        "frequency_ratio_interval": list(interval),
    }
    covering = sum(1 for o in outcomes if o["covers"])
    recommendation["reason"] = (
        f"the least settling time ({best['settling_time_s']:.6g} s) of the {covering} of {len(outcomes)} candidates "
        f"whose 5 % band covers the lowest mode's 95 % interval of f_n"
    )
    return body


# --- the route --------------------------------------------------------------------------------------------


def _csv_example() -> str:
    """0.4 s at 1 kHz of an accelerometer on a 40 Hz mode (zeta 0.02) seen by x and y, with gravity on z and
    noise of std 0.01 (seeded): a complete record that POST /v1/identify fits."""
    t = np.arange(400) * 1e-3
    wn = 2 * np.pi * 40.0
    mode = np.exp(-0.02 * wn * t) * np.cos(wn * np.sqrt(1 - 0.02**2) * t)
    noise = 0.01 * np.random.default_rng(0).standard_normal((3, t.size))
    columns = np.vstack([t, 0.8 * mode + noise[0], 0.3 * mode + noise[1], 9.81 + noise[2]]).T
    rows = "\n".join(f"{a:.3f},{x:.4f},{y:.4f},{z:.4f}" for a, x, y, z in columns)
    return "time_s,accel_x,accel_y,accel_z\n" + rows + "\n"


_CSV_EXAMPLE = _csv_example()
OPENAPI_BODY: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": IdentifyRequest.model_json_schema()},
            CSV_MEDIA_TYPE: {
                "schema": {"type": "string"},
                "example": _CSV_EXAMPLE,
                "description": "A header row, a time column (time_s, or the first column; seconds) and one or more "
                "signal columns; a column named command (or command_column) is the known command.",
            },
        },
    }
}


def _is_csv(content_type: str | None) -> bool:
    return (content_type or "").split(";", 1)[0].strip().lower() == CSV_MEDIA_TYPE


def _decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        rule = f"the CSV is not UTF-8 (byte {exc.start})"
        raise problems.ProblemError(
            "malformed-body", rule, field="body", errors=[{"field": "body", "value": None, "rule": rule}]
        ) from None


@router.post(
    "/identify",
    summary="Identify vibration modes from a record (JSON free vibration, or a CSV measurement) and recommend a design",
    response_model=IdentifyResponse | IdentifyMeasurementResponse,
    responses=problems.responses(400, 413, 422, 503),
    openapi_extra=OPENAPI_BODY,
)
async def identify_mode(
    body: Annotated[Any, Body(openapi_examples=IDENTIFY_EXAMPLES)],
    request: Request,
    settings: SettingsDep,
    pool: PoolDep,
    threads: ThreadsDep,
    params: Annotated[MeasurementParams, Query()],
) -> NumpyJSONResponse:
    """**application/json** (``time_s``, ``signal``): fit A e^(sigma t) cos(Omega t + phi) + offset to a free
    vibration by least squares (Sec. V-A asks for the period T0 and the decay sigma, eq. 16, read from two
    peaks; the fit uses every sample and reports its quality), and tune the damped harmonic smoother. Records
    with fewer than 2 periods, fewer than 4 samples per period or no oscillation clearly above the noise are
    refused (422, field ``signal`` or ``time_s``). The query parameters apply to CSV bodies only.

    **text/csv**: a header row, a time column (``time_s``, or the first column; seconds, uniform or nearly:
    jitter is interpolated, a gap refused) and up to 16 signal columns (e.g. ``accel_x,accel_y,accel_z``), at
    most VIBFREE_MAX_SAMPLES rows. The fit starts at ``start_s``, else where a ``command`` column (the known
    command the record responds to) last changes (the residual vibration after the command ends is a free
    vibration), else at the record's largest excursion. Returns the Welch spectrum (rectangular window,
    summed over the signals, at most 2049 points), and per mode (its peaks start the fit) the natural
    frequency and damping ratio of a sum of damped sinusoids fitted to every signal at once (shared
    frequencies and decays; scipy.optimize.least_squares by variable projection) with 95 % intervals from
    the fit's covariance (Student t), the record's quality and warnings. With ``displacement`` or
    ``target_velocity`` (and ``max_velocity``, ``max_acceleration``, ``max_jerk``), ``recommended`` is the
    request, ready to POST to its endpoint, of the design that settles first among those whose returned 5 %
    band covers the lowest mode's interval: time-optimal (robust over the interval, and nominal), every
    catalogue shaper, STAP with frequency_uncertainty, damped harmonic smoothers; ``recommendation.candidates``
    lists each with its settling time and band."""
    if not _is_csv(request.headers.get("content-type")):
        if params.has_move() or request.query_params:
            name = next(iter(request.query_params), "displacement")
            raise InvalidParameter(
                name, request.query_params.get(name), "query parameters apply to text/csv bodies only"
            )
        try:
            record = IdentifyRequest.model_validate(body)
        except ValidationError as exc:
            raise RequestValidationError(
                [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_url=False)]
            ) from None
        answer = await threads.run(identify_respond, record, settings, deadline_s=settings.thread_deadline_s)
        return NumpyJSONResponse(answer)
    text = _decode(body if isinstance(body, bytes) else str(body).encode())

    answer = await identify_csv(
        text,
        params,
        runner(settings, pool, threads),
        max_rows=settings.max_samples,
        threads=threads,
        deadline_s=settings.thread_deadline_s,
    )
    return NumpyJSONResponse(answer)
