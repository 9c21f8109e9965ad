"""The identify use case: vibration modes from a measured record, and a design for them.

A free vibration (JSON ``time_s``, ``signal``) is fitted with one damped sinusoid (Biagiotti eq. 16, the two-peak
estimate still reported for comparison) and gives the tuned smoother. A measured record (CSV: a time column and one
or more signal columns, optionally the known command) gives its Welch spectrum, peaks and a sum of damped sinusoids
fitted per mode with 95 % intervals (optim.identification.modal), the record's quality, and with a move and limits
the fastest design whose 5 % band covers the lowest mode's interval (app.services.recommend), each candidate run
through the family endpoints' use case (app.services.profile.profile). The route (app.routers.identify), the Python
API and the CLI call it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import ValidationError

from app import problems
from app.presenters import present
from app.schemas.family import ProfileRequest
from app.schemas.identify import MeasurementParams
from app.schemas.registry import REQUEST_SCHEMAS
from app.schemas.simulate import check_sample_count
from app.schemas.smoothers import IdentifyRequest
from app.services import printer
from app.services import profile as profiles
from app.services.recommend import Move, MoveLimits, RunOne, plant_interval, recommend, recommendation_candidates
from app.settings import Settings
from models.errors import InvalidParameter
from models.plants import FREQUENCY_MAX_HZ, FREQUENCY_MIN_HZ
from optim.families.input_shaped.calibration import normalized
from optim.families.smoother.smoothers import identify, tuned_duration_s, vibration_free_durations_s
from optim.identification.decay_start import identify_free_decay
from optim.identification.excitation import excitation_of
from optim.identification.formats import parse_rrf_csv
from optim.identification.modal import CONFIDENCE, FittedMode, IdentifiedMode, ModalIdentification
from optim.identification.record import uniform_record
from optim.identification.record_csv import parse_record_csv
from optim.registry import FAMILIES
from runtime.executor import Executor, InlineExecutor


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


def parse_family_request(family: str, body: Mapping[str, Any]) -> ProfileRequest:
    """A recommended request parsed by its endpoint's schema (an InvalidParameter naming the field if not)."""
    try:
        return REQUEST_SCHEMAS[family].model_validate(body)
    except ValidationError as exc:
        err = exc.errors()[0]
        raise InvalidParameter(problems.field_path(tuple(err["loc"])), None, str(err["msg"])) from None


def runner(settings: Settings, executor: Executor, threads: Executor = profiles.INLINE) -> RunOne:
    """A ``run_one``: each candidate through the family endpoints' service layer (app.services.profile.profile) on
    ``executor`` and ``threads``: the route's solver pool and design threads, or in-process."""

    async def run_one(family: str, body: dict[str, Any]) -> dict[str, Any]:
        request = parse_family_request(family, body)
        return await profiles.profile(FAMILIES[family], request, settings, executor, threads)

    return run_one


def in_process_runner(settings: Settings) -> RunOne:
    """A ``run_one`` without a server or a solver pool (for the CLI): the candidates run in this process, the
    solver ones one after the other (IPOPT is not thread-safe)."""
    return runner(settings, InlineExecutor())


def _mode_dict(mode: IdentifiedMode) -> dict[str, Any]:
    """An identified mode as the answer's object: its fields, in order (app.presenters)."""
    body: dict[str, Any] = present(mode)
    return body


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


@dataclass(frozen=True)
class _Fitted:
    """A CSV record's fit: the identification, its sample count, the target's shaper fields (None without one),
    its format and the warnings of its parse."""

    result: ModalIdentification
    samples: int
    shaper: dict[str, Any] | None
    format: str
    warnings: list[str]


def identify_record_csv(text: str, params: MeasurementParams, max_rows: int) -> _Fitted:
    """Parse and fit a CSV record (pure: no I/O). A Klipper resonance CSV, or a record of a swept excitation
    (optim.identification.excitation), has no free decay to fit: app.services.printer answers it (raised as its
    answer: _SpectrumAnswer)."""
    fmt = printer.record_format(text, params)
    if fmt == "klipper_psd":
        raise _SpectrumAnswer(printer.psd_answer(text, params, max_rows))
    warnings: list[str] = []
    if fmt == "rrf_accelerometer":
        record, warnings = parse_rrf_csv(text, max_rows=max_rows)
    else:
        record = parse_record_csv(text, max_rows=max_rows, command_column=params.command_column)
    if record.command is None and params.start_s is None:
        dt, signals, _ = uniform_record(record.time_s, np.atleast_2d(record.signals))
        if excitation_of(signals, 1.0 / dt) == "sweep":
            answer = printer.sweep_answer(record, fmt, params)
            answer.body["warnings"] = [*warnings, *answer.body["warnings"]]
            raise _SpectrumAnswer(answer)
    result = identify_free_decay(record, max_modes=params.max_modes, start_s=params.start_s)
    shaper = None
    if params.target is not None:
        frequency, psd = printer.record_psd(record)
        mode, _ = plant_interval(result.modes)
        shaper = printer.shaper_recommendation(frequency, normalized(frequency, psd), params, [], mode)
    return _Fitted(result, int(record.time_s.size), shaper, fmt, warnings)


class _SpectrumAnswer(Exception):
    """Not an error: the answer of a record without a free decay, raised from the design thread."""

    def __init__(self, answer: printer.SpectrumAnswer) -> None:
        super().__init__("a spectrum's answer")
        self.answer = answer


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
    app.services.profile.profile; a caller without a server (the CLI) passes its own runner, or None for no
    recommendation."""
    params.check()
    # the fit, in the route's design threads (runtime.threads: bounded admission, deadline_s), or in-process
    try:
        fitted = await threads.run(identify_record_csv, text, params, max_rows, deadline_s=deadline_s)
    except _SpectrumAnswer as spectrum:
        body, modes = spectrum.answer.body, spectrum.answer.modes
        if modes:
            await _design_for(body, modes, params, run_one, lead=body["recommendation"]["reason"])
        elif params.has_move():
            body["recommendation"]["reason"] += "; design: none (no mode was identified with a 95 % interval)"
        return body
    result, shaper = fitted.result, fitted.shaper
    body = {"format": fitted.format, **_measurement_body(result, fitted.samples)}
    body["warnings"] = [*fitted.warnings, *body["warnings"]]
    body["recommended"] = None
    body["recommendation"] = {"reason": "", "candidates": [], **(shaper or {})}
    lead = body["recommendation"].pop("shaper_reason") if shaper is not None else None
    await _design_for(body, result.modes, params, run_one, lead)
    return body


async def _design_for(
    body: dict[str, Any],
    modes: Sequence[FittedMode],
    params: MeasurementParams,
    run_one: RunOne | None,
    lead: str | None,
) -> None:
    """The recommendation's plant, interval, design and reason for the identified ``modes``; ``lead`` (the shaper's
    reason, or a spectrum's note) comes first in the reason, followed by the design's where a move was given."""
    recommendation = body["recommendation"]
    mode, interval = plant_interval(modes)
    recommendation["plant"] = {
        "kind": "mode",
        "natural_frequency_hz": mode.natural_frequency_hz,
        "damping_ratio": mode.damping_ratio,
    }
    recommendation["frequency_ratio_interval"] = list(interval)
    await _recommend_design(body, modes, interval, params, run_one)
    if lead is not None:
        move = f"; design: {recommendation['reason']}" if params.has_move() else ""
        recommendation["reason"] = f"{lead}{move}"


async def _recommend_design(
    body: dict[str, Any],
    modes: Sequence[FittedMode],
    interval: tuple[float, float],
    params: MeasurementParams,
    run_one: RunOne | None,
) -> None:
    """``body["recommended"]`` and ``recommendation``'s candidates and reason: the fastest design for the move."""
    recommendation = body["recommendation"]
    if not params.has_move():
        recommendation["reason"] = (
            "no move given: add displacement or target_velocity (and max_velocity, max_acceleration, max_jerk) "
            "as query parameters for a recommended design"
        )
        return
    if run_one is None:
        recommendation["reason"] = "no runner given: the candidates were not run"
        return
    move = Move(params.displacement, params.target_velocity)
    limits = MoveLimits(params.max_velocity, params.max_acceleration, params.max_jerk)
    candidates = recommendation_candidates(modes, move, limits)
    chosen, outcomes = await recommend(candidates, run_one, interval)
    recommendation["candidates"] = outcomes
    if chosen is None:
        recommendation["reason"] = (
            "no candidate's 5 % band covers the interval within these limits (see candidates[].reason)"
        )
        return
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
