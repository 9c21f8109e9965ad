"""The input-shaping family (Chatlatanagulchai & Pongpanich): shaped velocity commands whose baseline
respects the drive's acceleration limit.

The shaped command v_s is the baseline v_b convolved with the impulses (positive, summing to one, so
|v_s| never exceeds the baseline's peak, nor its slope the baseline's where the copies do not
overlap). The modified baseline (Sec. 4) keeps v_s within the limit when t_(i+1) - t_i >= Delta;
``auto`` (the default) takes the fastest baseline whose shaped command meets the limits.

What the drive makes of v_s: with a velocity command (rest-to-velocity, Fig. 5) a rate limiter at
the acceleration limit; with a rest-to-rest move the drive is in position mode and its profile
generator follows the shaped position reference time-optimally within the acceleration and
velocity limits (``models.drives.follow_position``), so it arrives at the displacement, where a
rate limiter on the velocity would lose (or gain) distance whenever it lags. Either is the identity
for a command within the limit; the load is simulated with its output.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from models.commands import PiecewiseCommand
from models.drives import follow_position, rate_limit
from models.errors import Infeasible, InvalidParameter
from models.shapers import ImpulseSequence, RampTrain, shape_command
from models.torque import peak_motor_torque_nm as exact_peak_motor_torque_nm
from optim.families.input_shaped.baseline_choice import ShaperPlan, plan
from optim.families.input_shaped.firmware_blocks import firmware_block, shaper_residual_percent
from optim.families.input_shaped.options import MAX_SHAPED_MODES, MAX_SHAPED_RAMPS, InputShapedOptions
from optim.families.input_shaped.report import (
    BaselineReport,
    ImpulsesReport,
    InputShapedExtras,
    InputShapedReport,
    shaper_report,
)
from optim.families.input_shaped.shapers import (
    MAX_COMMAND_S,
    ShaperDesign,
    design_for_modes,
    step_baseline,
)
from optim.family import BaseFamily, Candidate, Design, Grid, Profile, Run, profile_at_instants
from optim.problem import Problem
from optim.results import Finish
from optim.synthesis import nominal_percentage_vibration, profile_arrays, simulated_metrics

TORQUE_ITERATIONS = 8  # lowering the acceleration limit until the motor torque fits: 2-3 passes seen
TORQUE_SLACK = 1e-9  # a design is kept when its exact torque peak is this far below the limit (round-off)
COMPARED_SHAPERS = ("zv", "mzv", "zvd", "ei")  # compare's rows: the shapers users set in their firmware


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


def _largest_gap(first: PiecewiseCommand, second: PiecewiseCommand) -> float:
    """max |v_1 - v_2|: both velocities are piecewise linear, so the breakpoints suffice."""
    t = np.union1d(first.time_s, second.time_s)
    return float(np.max(np.abs(first.evaluate(1, t) - second.evaluate(1, t))))


def _drive(command: PiecewiseCommand, limit: float | None, top: float | None, rest_to_rest: bool) -> PiecewiseCommand:
    """What the drive makes of a shaped command: itself within the acceleration limit; else a position-mode
    follower of a rest-to-rest staircase (so it arrives) or the paper's velocity rate limiter (Fig. 5)."""
    peak = None if limit is None else command.peak_abs(2)  # None: a velocity step
    if limit is None or (peak is not None and peak <= limit * (1.0 + 1e-12)):
        return command
    if rest_to_rest and peak is None:  # a staircase: the position-mode drive
        return follow_position(command, limit, top)
    return rate_limit(command, limit)  # a velocity step, or ramps over the limit by round-off


def _commands(problem: Problem, chosen: ShaperPlan, shaper: ImpulseSequence, limit: float | None) -> Commands:
    """v_b, v_s = v_b * impulses, v_a = what the drive makes of v_s, and the plain shaped step after the
    drive; refuses commands longer than the service simulates before building them."""
    baseline, velocity, cruise_s = chosen.baseline, chosen.velocity, chosen.cruise_s
    base_train, plain_train = baseline.train(), step_baseline(velocity).train()
    if cruise_s is not None:
        base_train, plain_train = base_train.pulse(cruise_s), plain_train.pulse(cruise_s)
    shaped_train, plain_shaped = base_train.shaped(shaper), plain_train.shaped(shaper)
    longest = max(shaped_train.end_s, plain_shaped.end_s)
    if limit is not None:  # the drive lags by at most the command's total variation over a
        longest = max(
            shaped_train.end_s + float(np.sum(np.abs(shaped_train.height))) / limit,
            plain_shaped.end_s + float(np.sum(np.abs(plain_shaped.height))) / limit,
        )
    _check_length(longest, shaper, chosen, limit)
    shaped = shaped_train.to_command()
    plain = plain_shaped.to_command()
    rest_to_rest, top = cruise_s is not None, problem.limits.max_velocity
    commands = Commands(
        base_train.to_command(),
        shaped,
        _drive(shaped, limit, top, rest_to_rest),
        _drive(plain, limit, top, rest_to_rest),
        shaped_train,
        shaper,
        baseline.ramp_time_s if baseline.kind != "step" else None,
    )
    _check_length(max(commands.end_s, float(commands.plain_limited.time_s[-1])), shaper, chosen, limit)
    return commands


def peak_motor_torque_nm(problem: Problem, command: PiecewiseCommand) -> float | None:
    """sup over all time of |motor torque| (inertial plus shaft torque, two_inertia) of the drive's command
    (piecewise-constant acceleration), exact in closed form per piece from the modal state
    (``models.torque``): its work grows with the command's breakpoints, not with the mode's frequency or the
    command's length. None without a torque limit or a mode."""
    if problem.limits.max_torque_nm is None or not problem.plant.modes():
        return None
    return exact_peak_motor_torque_nm(problem.plant, command)


def _overshoot(command: PiecewiseCommand, limit: float | None) -> float:
    """How far (relative) a ramp command's slope passes the limit; 0 for a staircase (the drive's business)."""
    peak = None if limit is None else command.peak_abs(2)
    return 0.0 if peak is None or limit is None else max(peak / limit - 1.0, 0.0)


def _designed(
    problem: Problem, options: InputShapedOptions, shaper: ImpulseSequence, limit: float | None
) -> tuple[ShaperPlan, Commands]:
    """The plan and commands for the drive's limit. The command's kinks sit on merged breakpoints (moved by
    up to 2e-9 s, or 1e-12 of the command's length), which can put a short ramp's slope above the limit by
    round-off (up to 2e-8 seen): then the baseline is redesigned twice that much inside the limit."""
    design_limit = limit
    for _ in range(3):  # one pass almost always; a second where round-off showed
        chosen = plan(problem, options, shaper, design_limit)
        commands = _commands(problem, chosen, shaper, limit)
        over = _overshoot(commands.shaped, limit)
        if over <= 1e-12 or design_limit is None:
            break
        design_limit *= 1.0 - 2.0 * over
    return chosen, commands


def within_torque(
    problem: Problem, options: InputShapedOptions, shaper: ImpulseSequence
) -> tuple[ShaperPlan, Commands, float | None]:
    """The plan and commands at the problem's acceleration limit, lowered where the motor torque would pass
    limits.max_torque_nm: M / (J_M + J_L) (Cusimano eq. 19) bounds the inertial torque only, the shaft adds
    J_L times the load's excess acceleration. The torque scales about as the limit, so each pass scales the
    limit by M / peak (less 1e-4); refused when TORQUE_ITERATIONS passes do not fit."""
    limit = problem.acceleration_limit
    for _ in range(TORQUE_ITERATIONS):  # 1 pass without a torque limit, 2-3 with one
        chosen, commands = _designed(problem, options, shaper, limit)
        peak = peak_motor_torque_nm(problem, commands.limited)
        top = problem.limits.max_torque_nm
        if peak is None or top is None or peak <= top * (1.0 - TORQUE_SLACK) or limit is None:
            return chosen, commands, limit
        if not math.isfinite(peak):  # not seen: under an acceleration limit the drive never steps its velocity
            raise Infeasible(
                "the drive's command steps its velocity, so the motor torque is impulsive", "limits.max_torque_nm"
            )
        limit *= top / peak * (1.0 - 1e-4)
    raise Infeasible(
        f"the motor torque still peaks at {peak:.6g} N m > limits.max_torque_nm = {top:.6g} after lowering the "
        f"acceleration limit {TORQUE_ITERATIONS} times (to {limit:.6g})",
        "limits.max_torque_nm",
    )


def _drive_name(unchanged: bool, rest_to_rest: bool) -> str:
    if unchanged:
        return "none: the shaped command meets the limits and the drive passes it unchanged"
    return "position follower (time-optimal, arrives)" if rest_to_rest else "velocity rate limiter (Fig. 5)"


def _check_length(longest: float, shaper: ImpulseSequence, chosen: ShaperPlan, limit: float | None) -> None:
    if longest > MAX_COMMAND_S:
        raise Infeasible(
            f"the command could last up to {longest:.6g} s (shaper {shaper.duration_s:.6g} s, ramp "
            f"{chosen.baseline.ramp_time_s:.6g} s"
            + (f", cruise {chosen.cruise_s:.6g} s" if chosen.cruise_s is not None else "")
            + (f", velocity {abs(chosen.velocity):.6g} at {limit:.6g} per s" if limit is not None else "")
            + f"), beyond the {MAX_COMMAND_S:g} s this service simulates",
            "limits.max_acceleration" if limit is not None else None,
        )


def baseline_report(chosen: ShaperPlan, requested: str) -> BaselineReport:
    baseline, velocity, cruise_s = chosen.baseline, chosen.velocity, chosen.cruise_s
    return BaselineReport(
        kind=baseline.kind,
        requested=requested,
        choice=chosen.reason,
        alternatives=chosen.alternatives,
        cruise_choice=None
        if cruise_s is None
        else f"cruise {abs(velocity):.6g}: the earliest-ending {baseline.kind} move within limits.max_velocity "
        "(the shaped command never moves faster than its baseline's cruise)",
        move="rest_to_velocity" if cruise_s is None else "rest_to_rest",
        velocity=velocity,
        cruise_time_s=cruise_s,
        step_times_s=baseline.step_times_s,
        step_heights=baseline.step_heights,
        ramp_time_s=baseline.ramp_time_s,
        method=baseline.method,
    )


def firmware_residual(problem: Problem, commands: Commands) -> Callable[[ImpulseSequence], float]:
    """The percentage vibration a firmware's impulses leave at the plant's first mode with this design's
    baseline (the baseline shaped by them, exactly: models.shapers.shape_command), in the definition of
    metrics.percentage_vibration; 100 V of the impulses alone (its value on a step) where that is not
    representable."""

    mode = problem.plant.modes()[0]
    seen: dict[bytes, float] = {}  # the firmwares often apply the same impulses (a named ZVD, a custom one)

    def residual(impulses: ImpulseSequence) -> float:
        key = impulses.amplitudes.tobytes() + impulses.times_s.tobytes()
        if key not in seen:
            try:
                value = nominal_percentage_vibration(problem, shape_command(commands.baseline, impulses))
            except InvalidParameter:
                value = None
            seen[key] = shaper_residual_percent(impulses, mode) if value is None else value
        return seen[key]

    return residual


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

    def not_applicable(self, problem: Problem) -> str | None:
        if problem.limits.max_jerk is not None:
            return (
                "limits.max_jerk: input-shaped commands are shaped steps and ramps, whose acceleration steps make "
                "the jerk impulsive; use a smoother, STAP or the pseudo-polynomial family under a jerk limit"
            )
        return None

    def default_options(self, problem: Problem) -> InputShapedOptions:
        """ZVD with the automatic baseline (the fastest that meets the limits) at the fastest cruise."""
        return InputShapedOptions()

    def candidates(self, problem: Problem) -> tuple[Candidate, ...]:
        """One row per shaper users compare (ZV, MZV, ZVD, EI), each in its own group, automatic baseline."""
        base = self.default_options(problem)
        return tuple(
            Candidate(f"{self.name}/{name}", replace(base, shaper=name), f"{self.name}/{name}")
            for name in COMPARED_SHAPERS
        )

    def design(self, problem: Problem, options: InputShapedOptions) -> Design:

        design = shaper_design(problem, options)
        shaper, limit = design.impulses, problem.acceleration_limit
        steps = options.baseline_steps if options.baseline == "multi_step" else 2
        if len(shaper.amplitudes) * steps > MAX_SHAPED_RAMPS:
            raise InvalidParameter(
                "baseline_steps" if options.baseline == "multi_step" else "shaper",
                f"{len(shaper.amplitudes)} impulses x {steps} steps",
                f"the shaped command would have more than {MAX_SHAPED_RAMPS} ramps; use fewer steps, modes or "
                "derivatives",
            )
        chosen, commands, limit = within_torque(problem, options, shaper)
        velocity = chosen.velocity
        warnings = []
        if limit is not None and problem.acceleration_limit is not None and limit < problem.acceleration_limit:
            warnings.append(
                f"acceleration limit lowered from {problem.acceleration_limit:.6g} to {limit:.6g} so that the motor "
                "torque (the inertia's and the shaft's) stays within limits.max_torque_nm"
            )
        unchanged = limit is None or _largest_gap(commands.shaped, commands.limited) <= 1e-9 * abs(velocity)
        if not unchanged:
            drive = (
                "the drive's position-mode profile generator follows the shaped position reference time-optimally "
                "within the limits and arrives at the displacement"
                if chosen.cruise_s is not None
                else "the drive's rate limiter ramps the velocity at the limit (Fig. 5)"
            )
            warnings.append(
                f"the shaped command breaks the acceleration limit ({chosen.baseline.kind} baseline): {drive}; the "
                "plant receives that command (rate_limited), which the load and metrics simulate, so the shaper no "
                "longer cancels the residual as designed; baseline 'auto' keeps the shaped command within the limit"
            )
        steps_in_command = bool(np.any(commands.shaped_train.rise_s == 0.0))
        summary = InputShapedReport(
            shaper=shaper_report(design),
            baseline=baseline_report(chosen, options.baseline),
            acceleration_limit=limit,
            drive=_drive_name(unchanged, chosen.cruise_s is not None),
            shaped_peak_acceleration=None if steps_in_command else commands.shaped_train.max_slope(),
            passes_limiter_unchanged=unchanged,
            duration_s=commands.end_s,
            firmware=firmware_block(design, firmware_residual(problem, commands)),
        )
        end_s = max(commands.end_s, float(commands.plain_limited.time_s[-1]))
        return Design(commands.limited, summary, tuple(warnings), end_s=end_s, detail=commands)

    def profile(self, design: Design, sampled: PiecewiseCommand, grid: Grid) -> Profile:
        """The shaped command sent to the drive (v_s); the load is simulated with what the drive makes of it."""

        return profile_arrays(design.detail.shaped.resampled(grid.period_s, grid.horizon_s))

    def profile_at(self, design: Design, sampled: PiecewiseCommand, time_s: NDArray[np.float64]) -> Profile:
        """The shaped command sent to the drive (as ``profile``), at the instants."""
        return profile_at_instants(design.detail.shaped, time_s)

    def finish(self, problem: Problem, design: Design, run: Run) -> Finish:

        commands: Commands = design.detail
        grid = run.grid
        plain = commands.plain_limited
        room = max(problem.max_samples - plain.time_s.size - 2, 1)
        end = max(grid.horizon_s, float(plain.time_s[-1]))
        period = max(grid.period_s, (end - float(plain.time_s[0])) / room)  # the residual is exact at any period
        extras = InputShapedExtras(
            rate_limited=profile_arrays(run.command),
            baseline=profile_arrays(commands.baseline.resampled(grid.period_s, grid.horizon_s)),
            impulses=ImpulsesReport(commands.impulses.amplitudes, commands.impulses.times_s),
            ramp_time_s=commands.ramp_time_s,
            unmodified=simulated_metrics(problem, plain.resampled(period, end)),
        )
        return Finish(extras=extras)
