"""Input shapers under an acceleration limit (Chatlatanagulchai & Pongpanich) and the shaper family.

``respond`` builds the whole response body of POST /v1/profiles/input-shaped without HTTP, so
that other endpoints (a future /v1/compare) can call it directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Body, Depends, Query, Request, Response

from app import problems
from app.examples import CHATLATANAGULCHAI_EQ3
from app.responses import CSV_RESPONSE_DOC, CsvFormat, NumpyJSONResponse, negotiate
from app.schemas.family import family_response, sample_count_check
from app.schemas.plants import to_plant
from app.schemas.shapers import MAX_SHAPED_MODES, InputShapedRequest, InputShapedResponse, ShaperCatalogue
from app.schemas.simulate import metrics_out, profile_out
from app.settings import Settings, get_settings
from models.commands import PiecewiseCommand
from models.errors import Infeasible, InvalidParameter
from models.plants import Plant
from models.shapers import ImpulseSequence, RampTrain, percentage_vibration, rate_limit
from models.simulation import metrics, simulate
from optim.shapers import (
    MAX_COMMAND_S,
    Baseline,
    ShaperDesign,
    catalogue,
    design_baseline,
    design_for_modes,
    fastest_cruise_velocity,
    step_baseline,
)

router = APIRouter(prefix="/v1", tags=["shapers"])

DEFAULT_SAMPLES = 2000
DEFAULT_TAIL_PERIODS = 5.0  # as every family: the load's free motion for 5 periods after the move
BAND_THRESHOLD = 0.05

_PAPER = {"plant": CHATLATANAGULCHAI_EQ3, "shaper": "zvd", "target_velocity": 1.0, "acceleration_limit": 0.1}
INPUT_SHAPED_EXAMPLES: dict[str, dict[str, Any]] = {
    "paper_modified_zvd": {
        "summary": "Sec. 4: ZVD with the modified baseline, unit velocity, a = 0.1 (Fig. 8 bottom)",
        "description": "The eq. (3) plant (omega_n = 0.57703 rad/s, zeta = 0.057724). ZVD amplitudes (0.2973, 0.4959, "
        "0.2068) at (0, 5.4535, 10.9071) s from the exact poles; Delta = a1 max A_i / a = 4.959 s. The shaped "
        "command passes the limiter unchanged and the residual of x1 vanishes.",
        "value": {**_PAPER, "baseline": "modified", "horizon_s": 60.0, "sample_period_s": 0.05},
    },
    "paper_step_zvd": {
        "summary": "Sec. 3.2: the plain ZVD-shaped step, distorted by the limit a = 0.1 (Fig. 6)",
        "description": "The drive's limiter turns the staircase into ramps of slope 0.1 and the residual returns.",
        "value": {**_PAPER, "baseline": "step", "horizon_s": 60.0, "sample_period_s": 0.05},
    },
    "paper_two_step_zv": {
        "summary": "Fig. 10: ZV with the two-step baseline (the paper's relations hold: A1 > A2)",
        "value": {**_PAPER, "shaper": "zv", "baseline": "multi_step", "horizon_s": 60.0, "sample_period_s": 0.05},
    },
    "rest_to_rest_ei": {
        "summary": "A rest-to-rest move of 10 m with an EI shaper (5 % tolerance) on the eq. (3) plant",
        "value": {
            **{k: v for k, v in _PAPER.items() if k != "target_velocity"},
            "shaper": "ei",
            "displacement": 10.0,
            "sensitivity": {"min_ratio": 0.5, "max_ratio": 1.5, "count": 101},
        },
    },
}


# ------------------------------------------------------------------------------------------
# The input-shaped profile


def _move(request: InputShapedRequest, shaper: ImpulseSequence) -> tuple[float, float | None, list[str]]:
    """(baseline velocity V, cruise time D/V of a rest-to-rest move or None, notes)."""
    target, displacement = request.target_velocity, request.displacement
    if (target is None) == (displacement is None):
        raise InvalidParameter(
            "target_velocity" if target is not None else "displacement",
            target if target is not None else None,
            "give exactly one of target_velocity (a velocity step) and displacement (a rest-to-rest move)",
        )
    if target is not None:
        if target == 0.0:
            raise InvalidParameter("target_velocity", target, "must be non-zero")
        if request.cruise_velocity is not None:
            raise InvalidParameter(
                "cruise_velocity", request.cruise_velocity, "applies to a rest-to-rest move (displacement) only"
            )
        return target, None, []
    assert displacement is not None
    if displacement == 0.0:
        raise InvalidParameter("displacement", displacement, "must be non-zero")
    notes = []
    velocity = request.cruise_velocity
    if velocity is None:
        if request.acceleration_limit is None:
            raise InvalidParameter(
                "cruise_velocity", None, "is required for a rest-to-rest move without acceleration_limit"
            )
        velocity = fastest_cruise_velocity(displacement, shaper, request.acceleration_limit)
        notes.append(
            f"cruise velocity {velocity:.6g}: the fastest modified rest-to-rest move that keeps the no-overlap "
            "condition"
        )
    return math.copysign(velocity, displacement), abs(displacement) / velocity, notes


def _sampled(command: PiecewiseCommand, period_s: float, end_s: float, max_samples: int) -> PiecewiseCommand:
    """The command on a uniform grid with its kinks kept; refuses more than ``max_samples``."""
    out = command.resampled(period_s, end_s)
    if out.time_s.size > max_samples:
        raise InvalidParameter(
            "sample_period_s",
            period_s,
            f"{out.time_s.size} samples (the grid plus the command's {command.time_s.size} kinks) exceed the cap "
            f"of {max_samples}; use a longer period",
        )
    return out


def _for_metrics(command: PiecewiseCommand, period_s: float, end_s: float, max_samples: int) -> PiecewiseCommand:
    """A sampling for metrics only: the same period when it fits the cap, else a coarser one (the
    residual is exact either way; only the settling check during the command uses the samples)."""
    end_s = max(end_s, float(command.time_s[-1]))
    room = max_samples - command.time_s.size - 2
    period_s = max(period_s, (end_s - float(command.time_s[0])) / max(room, 1))
    return command.resampled(period_s, end_s)


def _shaper_out(design: ShaperDesign) -> dict[str, Any]:
    impulses = design.impulses
    return {
        "name": design.name,
        "impulse_count": impulses.count,
        "duration_s": impulses.duration_s,
        "duration_periods": design.duration_periods,
        "vibration_tolerance": design.vibration_tolerance,
        "modes": [
            {
                "natural_frequency_hz": m.natural_frequency_hz,
                "natural_frequency_rad_s": m.natural_frequency_rad_s,
                "damping_ratio": m.damping_ratio,
            }
            for m in design.modes
        ],
        "residual_at_modes": [
            float(percentage_vibration(impulses, m.natural_frequency_rad_s, m.damping_ratio)) for m in design.modes
        ],
        "method": design.method,
        "reference": design.reference,
        "conditions_residual": design.conditions_residual,
    }


def _baseline_out(baseline: Baseline, velocity: float, cruise_s: float | None) -> dict[str, Any]:
    return {
        "kind": baseline.kind,
        "move": "rest_to_velocity" if cruise_s is None else "rest_to_rest",
        "velocity": velocity,
        "cruise_time_s": cruise_s,
        "step_times_s": baseline.step_times_s,
        "step_heights": baseline.step_heights,
        "ramp_time_s": baseline.ramp_time_s,
        "method": baseline.method,
    }


def _largest_gap(first: PiecewiseCommand, second: PiecewiseCommand) -> float:
    """max |v_1 - v_2|: both velocities are piecewise linear, so the breakpoints suffice."""
    t = np.union1d(first.time_s, second.time_s)
    return float(np.max(np.abs(first.evaluate(1, t) - second.evaluate(1, t))))


@dataclass(frozen=True)
class _Commands:
    """The exact velocity commands of one request (PiecewiseCommand, a breakpoint at every kink)."""

    baseline: PiecewiseCommand  # v_b
    shaped: PiecewiseCommand  # v_s, sent to the drive
    limited: PiecewiseCommand  # v_a, what the drive makes of v_s (Fig. 5)
    plain_limited: PiecewiseCommand  # the plain shaped step (or pulse) after the drive
    shaped_train: RampTrain

    @property
    def end_s(self) -> float:
        return max(float(c.time_s[-1]) for c in (self.baseline, self.shaped, self.limited))


def _design(request: InputShapedRequest) -> tuple[Plant, ShaperDesign]:
    plant = to_plant(request.plant)
    modes = plant.modes()
    if not modes:
        raise InvalidParameter("plant", plant.kind, "the plant has no vibration mode to shape")
    if request.shaped_modes == "all" and len(modes) > MAX_SHAPED_MODES:
        raise InvalidParameter(
            "shaped_modes",
            "all",
            f"the plant has {len(modes)} modes; at most {MAX_SHAPED_MODES} can be shaped together",
        )
    chosen = modes if request.shaped_modes == "all" else modes[:1]
    return plant, design_for_modes(request.shaper, chosen, request.vibration_tolerance)


MAX_SHAPED_RAMPS = 1000  # impulses x baseline steps: bounds the limiter's corners and the step programme


def _commands(
    baseline: Baseline, shaper: ImpulseSequence, velocity: float, cruise_s: float | None, limit: float | None
) -> _Commands:
    """v_b, v_s = v_b * impulses, v_a = rate_limit(v_s), and the plain shaped step after the limiter;
    refuses commands longer than the service simulates before building them."""
    base_train, plain_train = baseline.train(), step_baseline(velocity).train()
    if cruise_s is not None:
        base_train, plain_train = base_train.pulse(cruise_s), plain_train.pulse(cruise_s)
    shaped_train, plain_shaped = base_train.shaped(shaper), plain_train.shaped(shaper)
    longest = max(shaped_train.end_s, plain_shaped.end_s)
    if limit is not None:  # the limiter lags by at most the command's total variation over a
        longest = max(
            shaped_train.end_s + float(np.sum(np.abs(shaped_train.height))) / limit,
            plain_shaped.end_s + float(np.sum(np.abs(plain_shaped.height))) / limit,
        )
    if longest > MAX_COMMAND_S:
        raise Infeasible(
            f"the command could last up to {longest:.6g} s (shaper {shaper.duration_s:.6g} s, ramp "
            f"{baseline.ramp_time_s:.6g} s"
            + (f", cruise {cruise_s:.6g} s" if cruise_s is not None else "")
            + (f", velocity {abs(velocity):.6g} at {limit:.6g} per s" if limit is not None else "")
            + f"), beyond the {MAX_COMMAND_S:g} s this service simulates",
            "acceleration_limit" if limit is not None else None,
        )
    shaped = shaped_train.to_command()
    plain = plain_shaped.to_command()
    return _Commands(
        base_train.to_command(),
        shaped,
        rate_limit(shaped, limit) if limit is not None else shaped,
        rate_limit(plain, limit) if limit is not None else plain,
        shaped_train,
    )


def _grid(
    request: InputShapedRequest, commands: _Commands, period_of_mode_s: float, max_samples: int
) -> tuple[float, float]:
    """(horizon, sample period): the request's, or the command's end plus five natural periods
    sampled 2000 times; the count is capped."""
    end_s = commands.end_s
    if request.horizon_s is None:
        horizon_s = max(end_s, float(commands.plain_limited.time_s[-1])) + DEFAULT_TAIL_PERIODS * period_of_mode_s
    else:
        horizon_s = request.horizon_s
        if horizon_s < end_s:
            raise InvalidParameter("horizon_s", horizon_s, f"must be at least the command's end, {end_s:.6g} s")
    period_s = request.sample_period_s if request.sample_period_s is not None else horizon_s / DEFAULT_SAMPLES
    sample_count_check(horizon_s, period_s, max_samples)
    return horizon_s, period_s


def respond(request: InputShapedRequest, settings: Settings) -> dict[str, Any]:
    """The full response body of POST /v1/profiles/input-shaped."""
    plant, design = _design(request)
    shaper, limit = design.impulses, request.acceleration_limit
    steps = request.baseline_steps if request.baseline == "multi_step" else 1
    if len(shaper.amplitudes) * steps > MAX_SHAPED_RAMPS:
        raise InvalidParameter(
            "baseline_steps" if steps > 1 else "shaper",
            f"{len(shaper.amplitudes)} impulses x {steps} steps",
            f"the shaped command would have more than {MAX_SHAPED_RAMPS} ramps; use fewer steps, modes or derivatives",
        )
    velocity, cruise_s, warnings = _move(request, shaper)
    baseline = design_baseline(request.baseline, velocity, shaper, limit, request.baseline_steps)
    commands = _commands(baseline, shaper, velocity, cruise_s, limit)
    horizon_s, period_s = _grid(request, commands, design.modes[0].natural_period_s, settings.max_samples)
    sent, received, base = (
        _sampled(c, period_s, horizon_s, settings.max_samples)
        for c in (commands.shaped, commands.limited, commands.baseline)
    )
    unchanged = limit is None or _largest_gap(commands.shaped, commands.limited) <= 1e-9 * abs(velocity)
    if not unchanged:
        warnings.append(
            "the drive's acceleration limit changes the shaped command: the plant receives the rate-limited "
            "command (rate_limited), which the load and metrics simulate; baseline 'modified' keeps the shaped "
            "command within the limit"
        )
    steps_in_command = bool(np.any(commands.shaped_train.rise_s == 0.0))
    design_block = {
        "shaper": _shaper_out(design),
        "baseline": _baseline_out(baseline, velocity, cruise_s),
        "acceleration_limit": limit,
        "shaped_peak_acceleration": None if steps_in_command else commands.shaped_train.max_slope(),
        "passes_limiter_unchanged": unchanged,
    }
    body, _ = family_response(
        plant,
        received,
        design_block,
        sensitivity_request=request.sensitivity,
        settling_tolerance=request.settling_tolerance,
        warnings=warnings,
    )
    plain = _for_metrics(commands.plain_limited, period_s, horizon_s, settings.max_samples)
    body.update(
        {
            "profile": profile_out(sent),
            "rate_limited": body["profile"],
            "baseline": profile_out(base),
            "impulses": {"amplitudes": shaper.amplitudes, "times_s": shaper.times_s},
            "ramp_time_s": baseline.ramp_time_s if baseline.kind != "step" else None,
            "unmodified": metrics_out(metrics(simulate(plant, plain), request.settling_tolerance)),
        }
    )
    return body


@router.post(
    "/profiles/input-shaped",
    summary="Input-shaped velocity command under an acceleration limit (Chatlatanagulchai & Pongpanich)",
    response_model=InputShapedResponse,
    responses={**CSV_RESPONSE_DOC, **problems.responses(413, 422)},
)
def input_shaped_profile(
    request: Annotated[InputShapedRequest, Body(openapi_examples=INPUT_SHAPED_EXAMPLES)],
    settings: Annotated[Settings, Depends(get_settings)],
    http: Request,
    format: CsvFormat = None,
) -> Response:
    """Shape a velocity step or a rest-to-rest move for the plant's mode(s) and keep it within the
    drive's acceleration limit.

    The shaped command v_s (``profile``) is the baseline v_b (``baseline``) convolved with the
    impulses; the drive limits its slope (Fig. 5), giving v_a (``rate_limited``), which the load
    response and ``metrics`` simulate exactly. With the ``modified`` baseline (Sec. 4) the ramp
    time Delta = a1 max|A_i| / a keeps v_s within the limit, so v_a = v_s; it needs the no-overlap
    condition t_(i+1) - t_i >= Delta (the paper prints |A_i| in place of max|A_i| there), and a
    request that breaks it is answered as infeasible. ``multi_step`` uses the paper's two-step
    relations only where they hold (two impulses with A1 >= A2, as ZV); for other shapers (ZVD,
    where the relations give a negative step and a slope of 2a) it finds the fastest valid steps.
    ``unmodified`` gives the metrics of the plain shaped step after the limiter, for comparison.
    """
    return negotiate(http, respond(request, settings), "input-shaped profile (the shaped command sent to the drive)")


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
    entries, missing = catalogue(float(damping_ratio), float(vibration_tolerance), BAND_THRESHOLD)
    shapers = [
        {
            "name": e.name,
            "impulse_count": e.impulse_count,
            "duration_periods": e.duration_periods,
            "band_5_percent": list(e.band) if e.band else None,
            "band_width": e.band[1] - e.band[0] if e.band and None not in e.band else None,
            "amplitudes": list(e.amplitudes),
            "times_periods": list(e.times_periods),
            "method": e.method,
            "reference": e.reference,
        }
        for e in entries
    ]
    return NumpyJSONResponse(
        {
            "damping_ratio": damping_ratio,
            "vibration_tolerance": vibration_tolerance,
            "band_threshold": BAND_THRESHOLD,
            "shapers": shapers,
            "unavailable": [{"name": name, "reason": reason} for name, reason in missing],
        }
    )
