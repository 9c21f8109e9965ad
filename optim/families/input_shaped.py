"""The input-shaping family (Chatlatanagulchai & Pongpanich): shaped velocity commands whose baseline
respects the drive's acceleration limit.

The shaped command v_s is the baseline v_b convolved with the impulses; the drive limits its slope
(Fig. 5) to v_a, which the load is simulated with. The modified baseline (Sec. 4) keeps v_s within the
limit when t_(i+1) - t_i >= Delta.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np

from models.commands import PiecewiseCommand
from models.errors import Infeasible, InvalidParameter
from models.shapers import ImpulseSequence, RampTrain, percentage_vibration, rate_limit
from models.simulation import metrics, simulate
from optim.family import BaseFamily, Design, Grid, Profile, Run
from optim.problem import Problem
from optim.shapers import (
    DEFAULT_VIBRATION_TOLERANCE,
    MAX_COMMAND_S,
    Baseline,
    ShaperDesign,
    design_baseline,
    design_for_modes,
    fastest_cruise_velocity,
    step_baseline,
)

MAX_SHAPED_MODES = 3
MAX_SHAPED_RAMPS = 1000  # impulses x baseline steps: bounds the limiter's corners and the step programme


@dataclass(frozen=True)
class InputShapedOptions:
    shaper: str = "zvd"
    vibration_tolerance: float = DEFAULT_VIBRATION_TOLERANCE
    shaped_modes: Literal["first", "all"] = "first"
    baseline: Literal["step", "modified", "multi_step"] = "modified"
    baseline_steps: int = 2


@dataclass(frozen=True)
class Commands:
    """The exact velocity commands of one design (a breakpoint at every kink)."""

    baseline: PiecewiseCommand  # v_b
    shaped: PiecewiseCommand  # v_s, sent to the drive
    limited: PiecewiseCommand  # v_a, what the drive makes of v_s (Fig. 5)
    plain_limited: PiecewiseCommand  # the plain shaped step (or pulse) after the drive
    shaped_train: RampTrain
    impulses: ImpulseSequence
    ramp_time_s: float | None

    @property
    def end_s(self) -> float:
        return max(float(c.time_s[-1]) for c in (self.baseline, self.shaped, self.limited))


def _move(problem: Problem, shaper: ImpulseSequence, limit: float | None) -> tuple[float, float | None, list[str]]:
    """(baseline velocity V, cruise time D/V of a rest-to-rest move or None, notes)."""
    if problem.target_velocity is not None:
        return problem.target_velocity, None, []
    displacement = problem.move
    velocity = problem.limits.max_velocity
    notes = []
    if velocity is None:
        if limit is None:
            raise InvalidParameter(
                "limits.max_velocity", None, "is required for a rest-to-rest move without an acceleration limit"
            )
        velocity = fastest_cruise_velocity(displacement, shaper, limit)
        notes.append(
            f"cruise velocity {velocity:.6g}: the fastest modified rest-to-rest move that keeps the no-overlap "
            "condition"
        )
    return math.copysign(velocity, displacement), abs(displacement) / velocity, notes


def _largest_gap(first: PiecewiseCommand, second: PiecewiseCommand) -> float:
    """max |v_1 - v_2|: both velocities are piecewise linear, so the breakpoints suffice."""
    t = np.union1d(first.time_s, second.time_s)
    return float(np.max(np.abs(first.evaluate(1, t) - second.evaluate(1, t))))


def _commands(
    baseline: Baseline, shaper: ImpulseSequence, velocity: float, cruise_s: float | None, limit: float | None
) -> Commands:
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
            "limits.max_acceleration" if limit is not None else None,
        )
    shaped = shaped_train.to_command()
    plain = plain_shaped.to_command()
    return Commands(
        base_train.to_command(),
        shaped,
        rate_limit(shaped, limit) if limit is not None else shaped,
        rate_limit(plain, limit) if limit is not None else plain,
        shaped_train,
        shaper,
        baseline.ramp_time_s if baseline.kind != "step" else None,
    )


def _shaper_block(design: ShaperDesign) -> dict[str, Any]:
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


def _baseline_block(baseline: Baseline, velocity: float, cruise_s: float | None) -> dict[str, Any]:
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


def shaper_design(problem: Problem, options: InputShapedOptions) -> ShaperDesign:
    modes = problem.plant.modes()
    if not modes:
        raise InvalidParameter("plant", problem.plant.kind, "the plant has no vibration mode to shape")
    if options.shaped_modes == "all" and len(modes) > MAX_SHAPED_MODES:
        raise InvalidParameter(
            "shaped_modes",
            "all",
            f"the plant has {len(modes)} modes; at most {MAX_SHAPED_MODES} can be shaped together",
        )
    chosen = modes if options.shaped_modes == "all" else modes[:1]
    return design_for_modes(options.shaper, chosen, options.vibration_tolerance)


class InputShapedFamily(BaseFamily):
    name: ClassVar[str] = "input_shaped"
    endpoint: ClassVar[str] = "/v1/profiles/input-shaped"

    def default_options(self, problem: Problem) -> InputShapedOptions:
        """ZVD, with the modified baseline where an acceleration limit applies (else the plain step)."""
        return InputShapedOptions(baseline="modified" if problem.acceleration_limit is not None else "step")

    def fallback(self, problem: Problem, options: Any) -> InputShapedOptions | None:
        """The modified baseline needs t_(i+1) - t_i >= Delta; a single slower ramp always exists."""
        if options.baseline == "modified":
            return InputShapedOptions(**{**vars(options), "baseline": "multi_step", "baseline_steps": 1})
        return None

    def design(self, problem: Problem, options: InputShapedOptions) -> Design:
        design = shaper_design(problem, options)
        shaper, limit = design.impulses, problem.acceleration_limit
        steps = options.baseline_steps if options.baseline == "multi_step" else 1
        if len(shaper.amplitudes) * steps > MAX_SHAPED_RAMPS:
            raise InvalidParameter(
                "baseline_steps" if steps > 1 else "shaper",
                f"{len(shaper.amplitudes)} impulses x {steps} steps",
                f"the shaped command would have more than {MAX_SHAPED_RAMPS} ramps; use fewer steps, modes or "
                "derivatives",
            )
        velocity, cruise_s, warnings = _move(problem, shaper, limit)
        baseline = design_baseline(options.baseline, velocity, shaper, limit, options.baseline_steps)
        commands = _commands(baseline, shaper, velocity, cruise_s, limit)
        unchanged = limit is None or _largest_gap(commands.shaped, commands.limited) <= 1e-9 * abs(velocity)
        if not unchanged:
            warnings.append(
                "the drive's acceleration limit changes the shaped command: the plant receives the rate-limited "
                "command (rate_limited), which the load and metrics simulate; baseline 'modified' keeps the shaped "
                "command within the limit"
            )
        steps_in_command = bool(np.any(commands.shaped_train.rise_s == 0.0))
        summary = {
            "shaper": _shaper_block(design),
            "baseline": _baseline_block(baseline, velocity, cruise_s),
            "acceleration_limit": limit,
            "shaped_peak_acceleration": None if steps_in_command else commands.shaped_train.max_slope(),
            "passes_limiter_unchanged": unchanged,
            "duration_s": commands.end_s,
        }
        end_s = max(commands.end_s, float(commands.plain_limited.time_s[-1]))
        return Design(commands.limited, summary, tuple(warnings), end_s=end_s, detail=commands)

    def profile(self, design: Design, sampled: PiecewiseCommand, grid: Grid) -> Profile:
        """The shaped command sent to the drive (v_s); the load is simulated with what the drive makes of it."""
        from optim.synthesis import profile_arrays

        return profile_arrays(design.detail.shaped.resampled(grid.period_s, grid.horizon_s))

    def finish(self, problem: Problem, design: Design, run: Run) -> dict[str, Any]:
        from optim.synthesis import metrics_dict, profile_arrays

        commands: Commands = design.detail
        grid = run.grid
        plain = commands.plain_limited
        room = max(problem.max_samples - plain.time_s.size - 2, 1)
        end = max(grid.horizon_s, float(plain.time_s[-1]))
        period = max(grid.period_s, (end - float(plain.time_s[0])) / room)  # the residual is exact at any period
        unmodified = metrics(simulate(problem.plant, plain.resampled(period, end)), problem.settling.position_tolerance)
        return {
            "rate_limited": profile_arrays(run.command),
            "baseline": profile_arrays(commands.baseline.resampled(grid.period_s, grid.horizon_s)),
            "impulses": {"amplitudes": commands.impulses.amplitudes, "times_s": commands.impulses.times_s},
            "ramp_time_s": commands.ramp_time_s,
            "unmodified": metrics_dict(unmodified),
        }
