"""The baseline a shaper is applied to (Sec. 4 of Chatlatanagulchai and Pongpanich): the one requested, or
``auto``, the fastest whose shaped command meets the limits, at the fastest cruise within limits.max_velocity."""

from __future__ import annotations

import math
from dataclasses import dataclass

from models.errors import InvalidParameter
from models.shapers import ImpulseSequence
from optim.families.input_shaped.options import InputShapedOptions
from optim.families.input_shaped.report import BaselineAlternative
from optim.families.input_shaped.shapers import (
    Baseline,
    design_baseline,
    fastest_cruise_velocity,
    fastest_single_ramp_cruise,
    multi_step_baseline,
    single_ramp_baseline,
    step_baseline,
)
from optim.problem import Problem

AUTO_MULTI_STEP_MAX_IMPULSES = 5  # auto also tries multi-step baselines (linear programmes) on shapers this small


@dataclass(frozen=True)
class ShaperPlan:
    """The baseline of one design and why it was chosen: velocity V, cruise time D/V (rest-to-rest)."""

    baseline: Baseline
    velocity: float
    cruise_s: float | None
    reason: str
    alternatives: tuple[BaselineAlternative, ...] = ()


def shaped_end_s(baseline: Baseline, shaper: ImpulseSequence, cruise_s: float | None) -> float:
    """When the shaped command stops changing: the baseline (a pulse of ``cruise_s`` for a rest-to-rest
    move) convolved with the impulses."""
    train = baseline.train() if cruise_s is None else baseline.train().pulse(cruise_s)
    return train.shaped(shaper).end_s


def _cruise_velocity(problem: Problem, shaper: ImpulseSequence, kind: str, limit: float | None) -> float:
    """The signed cruise V of a rest-to-rest move: the fastest within limits.max_velocity for the kind of
    baseline (the shaped command's peak velocity is the baseline's, at most V)."""
    displacement, top = problem.move, problem.limits.max_velocity
    if limit is None:
        if top is None:
            raise InvalidParameter(
                "limits.max_velocity", None, "is required for a rest-to-rest move without an acceleration limit"
            )
        return math.copysign(top, displacement)
    if kind == "modified":
        return math.copysign(fastest_cruise_velocity(displacement, shaper, limit, top), displacement)
    if kind == "step" and top is not None:
        return math.copysign(top, displacement)
    return math.copysign(fastest_single_ramp_cruise(displacement, shaper, limit, top), displacement)


def _velocity_and_cruise(
    problem: Problem, shaper: ImpulseSequence, kind: str, limit: float | None
) -> tuple[float, float | None]:
    """(V, D/V): the target velocity of a rest-to-velocity move (no cruise), else the cruise and its time."""
    if problem.target_velocity is not None:
        return problem.target_velocity, None
    velocity = _cruise_velocity(problem, shaper, kind, limit)
    return velocity, abs(problem.move / velocity)


def _nominal_residual(problem: Problem, baseline: Baseline, shaper: ImpulseSequence, cruise_s: float | None) -> float:
    """The residual the shaped baseline leaves on the plant's first mode (position; velocity when the move
    ends moving), in the load's units: one sum over its breakpoints (models.sensitivity)."""
    from models.sensitivity import mode_residuals

    modes = problem.plant.modes()
    if not modes:
        return 0.0
    train = baseline.train() if cruise_s is None else baseline.train().pulse(cruise_s)
    try:
        command = train.shaped(shaper).to_command()
    except InvalidParameter:  # a move beyond the time range: refused later, with its reason
        return math.inf
    mode = modes[0]
    derivative = 0 if problem.rest_to_rest else 1
    amplitude, _ = mode_residuals(command, mode.natural_frequency_rad_s, mode.damping_ratio, derivative)
    return float(amplitude[0]) * problem.plant.load_move(1.0)


def _why(chosen: Baseline, single_ramp: bool) -> str:
    if chosen.kind == "modified":
        return "its shaped ramps do not overlap (t_(i+1) - t_i >= Delta, Sec. 4)"
    if single_ramp:
        return "the modified baseline's shaped ramps would overlap and break the limit"
    return "it ends before the single ramp"


def _auto(problem: Problem, shaper: ImpulseSequence, limit: float | None) -> ShaperPlan:
    """The fastest baseline whose shaped command meets the limits, by the shaped command's end: the
    plain step without an acceleration limit; else the shortest single ramp (the modified baseline where
    its ramps do not overlap, lengthened where they do) at its fastest cruise, against the multi-step
    baselines of Fig. 10 (2 to n steps) at the same speed, for shapers of at most
    AUTO_MULTI_STEP_MAX_IMPULSES impulses (each is a linear programme). Where the ramps must overlap the
    steps can end sooner (ZVD, a = 0.05 on the paper's plant: 26.84 s with 3 steps, 30.91 s with one ramp);
    where the modified ramp fits none can, as its second step starts at t_2 >= min gap >= Delta."""
    if limit is None:
        velocity, cruise = _velocity_and_cruise(problem, shaper, "step", limit)
        return ShaperPlan(step_baseline(velocity), velocity, cruise, "auto: no acceleration limit, so the plain step")
    velocity, cruise = _velocity_and_cruise(problem, shaper, "ramp", limit)
    options = [single_ramp_baseline(velocity, shaper, limit)]
    if options[0].kind != "modified" and shaper.count <= AUTO_MULTI_STEP_MAX_IMPULSES:
        options += [multi_step_baseline(velocity, shaper, limit, steps) for steps in range(2, shaper.count + 1)]
    ends = [shaped_end_s(b, shaper, cruise) for b in options]
    residuals = [_nominal_residual(problem, b, shaper, cruise) for b in options]
    # The earliest-ending of those that leave the least residual (an EI, which leaves some by design,
    # can leave three times more on a multi-step baseline); for a zero-residual shaper: the earliest.
    floor = min(residuals)
    least = [i for i, r in enumerate(residuals) if r <= floor * (1 + 1e-6) + 1e-12 * problem.load_move]
    best = min(least, key=lambda i: ends[i])
    alternatives = tuple(
        BaselineAlternative(b.kind, int(b.step_times_s.size), b.ramp_time_s, e, r)
        for b, e, r in zip(options, ends, residuals, strict=True)
    )
    reason = (
        f"auto: the {options[best].kind} baseline with {options[best].step_times_s.size} step(s), the earliest-ending "
        f"of those tried whose shaped command meets the limits and leaves the least residual at the first mode "
        f"(shaped end {ends[best]:.6g} s): "
        f"{_why(options[best], best == 0)}"
    )
    return ShaperPlan(options[best], velocity, cruise, reason, alternatives)


def plan(problem: Problem, options: InputShapedOptions, shaper: ImpulseSequence, limit: float | None) -> ShaperPlan:
    """The baseline and cruise of a design: ``auto``'s choice, or the requested kind at its fastest cruise
    within max_velocity (modified refuses where its ramps would overlap at the speed asked)."""
    if options.baseline == "auto":
        return _auto(problem, shaper, limit)
    kind = options.baseline
    velocity, cruise = _velocity_and_cruise(problem, shaper, kind, limit)
    baseline = design_baseline(kind, velocity, shaper, limit, options.baseline_steps)
    return ShaperPlan(baseline, velocity, cruise, f"requested: {kind}")
