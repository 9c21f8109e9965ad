"""The one synthesis pipeline every endpoint and compare use.

``synthesize(family, problem, options)``: the family's design, its command sampled to the horizon,
the simulated load, the metrics, the sensitivity, the limit check and the warnings, as a frozen
``Result``. The rules written once here:

- horizon: ``problem.horizon_s``, else the command's end plus 5 natural periods of the slowest mode;
- sampling: ``problem.sample_period_s``, else about 2000 samples over the horizon, rounded to 1, 2 or
  5 times a power of ten (coarser only where the sample cap demands it); corners are always kept;
- limits: a peak above a limit by more than 1e-9 of it, or an impulsive quantity under a limit, is
  a violation, reported as ``limits.<name>: ...`` in ``limit_violations`` and in ``warnings``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from models.commands import PiecewiseCommand
from models.errors import Infeasible, InvalidParameter, NotApplicable
from models.metrics import Metrics, metrics
from models.sensitivity import band_below, move_scale, residual_envelope, sensitivity
from models.simulation import Response, simulate
from optim.family import Design, Family, Grid, Profile, Run, SolverSummary
from optim.problem import TAIL_PERIODS, Limits, Problem, SensitivityGrid, nice_period
from optim.results import Block, MetricsReport, SensitivityCurve

LIMIT_RTOL = 1e-9  # a peak within this fraction above a limit counts as meeting it (round-off)
BAND_LEVEL = 0.05
MAX_SENSITIVITY_WORK = 20_000_000  # frequency points x damping ratios x breakpoints: about a second


@dataclass(frozen=True)
class Result:
    """One design through the pipeline: what the drive receives, what the load does, and what the family says."""

    family: str
    design: Design
    run: Run
    profile: Profile
    sensitivity: SensitivityCurve | None
    limit_violations: tuple[str, ...]
    warnings: tuple[str, ...]
    solver: SolverSummary | None
    extras: Block | None  # the family's own top-level blocks (Finish.extras)
    summary: Block  # the design block, completed after sampling
    percentage_vibration: float | None = None  # V at the nominal first mode, % (None: no mode)

    @property
    def metrics(self) -> Metrics:
        return self.run.metrics

    @property
    def metrics_report(self) -> MetricsReport:
        return MetricsReport(self.run.metrics, self.percentage_vibration)

    @property
    def response(self) -> Response:
        return self.run.response

    @property
    def command(self) -> PiecewiseCommand:
        return self.run.command


def synthesize(family: Family, problem: Problem, options: Any) -> Result:
    """Design, sample, simulate and evaluate one family's command for ``problem``."""
    reason = family.not_applicable(problem)
    if problem.in_motion and not getattr(family, "moves_in_motion", False):
        reason = f"{family.name} designs moves from rest: only time_optimal starts or ends in motion"
    if reason is not None:
        raise NotApplicable(reason)
    design = family.design(problem, options)
    return evaluate(family, problem, design)


def evaluate(family: Family, problem: Problem, design: Design) -> Result:
    """Everything after the design: the shared half of the pipeline."""
    grid = grid_of(problem, design)
    sampled = family.sample(problem, design, grid.period_s, grid.horizon_s)
    if sampled.time_s.size > problem.max_samples:
        raise InvalidParameter(
            "sample_period_s",
            grid.period_s,
            f"{sampled.time_s.size} samples (the grid and the command's corners) exceed the cap of "
            f"{problem.max_samples}; use a longer period",
        )
    response = simulate(problem.plant, sampled)
    run = Run(grid, sampled, response, metrics_of(problem, response))
    profile = family.profile(design, sampled, grid) or profile_arrays(sampled)
    _check_finite(problem, profile, _load_arrays(response))
    curve = None
    if problem.sensitivity is not None:
        zetas, ratios = _sensitivity_axes(problem, problem.sensitivity)
        _check_sensitivity_work(problem.sensitivity, zetas.size, ratios.size, sampled, problem.max_samples)
        curve = family.sensitivity(problem, design, ratios, zetas) or sensitivity_curve(problem, sampled, ratios, zetas)
    nominal = nominal_percentage_vibration(problem, sampled)
    finished = family.finish(problem, design, run)
    violations = limit_violations(problem.limits, run.metrics)
    if violations and not problem.allow_limit_violation:
        raise Infeasible(
            f"the {family.name} design breaks the limits ({'; '.join(violations)}); ask allow_limit_violation "
            "to see it anyway",
            violations[0].split(":")[0],
        )
    warnings = (*design.warnings, *finished.warnings, *violations)
    return Result(
        family=family.name,
        design=design,
        run=run,
        profile=profile,
        sensitivity=curve,
        limit_violations=violations,
        warnings=warnings,
        solver=design.solver,
        extras=finished.extras,
        summary=finished.design or design.summary,
        percentage_vibration=nominal,
    )


# --- the shared rules ------------------------------------------------------------------------


def horizon_of(problem: Problem, end_s: float) -> float:
    """``problem.horizon_s`` (>= the command's end), else the end plus 5 periods of the slowest mode; the end itself
    for a move ending with an acceleration (held after the end, its velocity would grow without bound: the next move
    continues it)."""
    accelerating = problem.final_state.acceleration != 0.0
    if accelerating and problem.horizon_s is not None and problem.horizon_s > end_s:
        raise InvalidParameter(
            "horizon_s",
            problem.horizon_s,
            f"a move ending with a non-zero final_state.acceleration has no tail after its end ({end_s:.6g} s): the "
            "next move continues it; omit horizon_s",
        )
    if accelerating:
        return end_s
    if problem.horizon_s is None:
        return end_s + TAIL_PERIODS * problem.slowest_period_s
    if problem.horizon_s < end_s:
        raise InvalidParameter("horizon_s", problem.horizon_s, f"must be >= the command's end ({end_s:.6g} s)")
    return problem.horizon_s


def grid_of(problem: Problem, design: Design, start_s: float = 0.0) -> Grid:
    """The sampling of the returned series; refuses a count above the cap before building anything."""
    corners = 0 if design.command is None else int(design.command.time_s.size)
    return grid_until(problem, design.command_end_s, corners, start_s)


def grid_until(problem: Problem, end_s: float, corners: int = 0, start_s: float = 0.0) -> Grid:
    """The sampling of a command ending at ``end_s`` with ``corners`` breakpoints of its own (``grid_of`` without
    a design: a family checking a duration before it designs)."""
    horizon = horizon_of(problem, end_s)
    span = max(horizon - start_s, 0.0)
    room = problem.max_samples - corners - 2
    if problem.sample_period_s is not None:
        period = problem.sample_period_s
        count = int(span / period) + 1
        if count > room:
            raise InvalidParameter(
                "sample_period_s",
                period,
                f"{count} samples over {span:.6g} s{f' (and {corners} corners)' if corners else ''} exceed the cap "
                f"of {problem.max_samples}; use a period >= {span / max(room - 1, 1):.3g} s",
            )
        return Grid(period, horizon)
    period = nice_period(span)
    if int(span / period) + 1 > room:
        period = nice_period(span, max(room - 1, 1))
    return Grid(period, horizon)


def metrics_of(problem: Problem, response: Response) -> Metrics:
    """The metrics with the problem's settling criteria (position band and vibration bound)."""
    return metrics(response, problem.settling.position_tolerance, vibration_window=problem.vibration_window)


def limit_violations(limits: Limits, result: Metrics) -> tuple[str, ...]:
    """Every requested limit the simulated command breaks, in one wording."""
    peaks = {
        "max_velocity": ("velocity", result.peak_velocity),
        "max_acceleration": ("acceleration", result.peak_acceleration),
        "max_jerk": ("jerk", result.peak_jerk),
        "max_torque_nm": ("motor torque", result.peak_motor_torque_nm),
    }
    out = []
    for name, limit in limits.items():
        if limit is None:
            continue
        quantity, peak = peaks[name]
        if peak is None:
            what = "undefined for this plant (two_inertia only)" if name == "max_torque_nm" else "impulsive"
            out.append(f"limits.{name}: the {quantity} is {what}")
        elif peak > limit * (1.0 + LIMIT_RTOL):
            out.append(f"limits.{name}: the {quantity} peaks at {peak:.9g} > {limit:.9g}")
    return tuple(out)


def _check_finite(problem: Problem, *blocks: Mapping[str, NDArray[np.float64] | None]) -> None:
    for block in blocks:
        for key, array in block.items():
            if array is not None and not np.all(np.isfinite(np.asarray(array, dtype=float))):
                raise InvalidParameter(problem.move_field, problem.move, f"the {key} overflows double precision")


# --- sensitivity -------------------------------------------------------------------------------


def _sensitivity_axes(problem: Problem, grid: SensitivityGrid) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    modes = problem.plant.modes()
    if not modes:
        raise InvalidParameter("sensitivity", "requested", "the plant has no vibration mode to evaluate it around")
    zetas = np.asarray(grid.damping_ratios or [modes[0].damping_ratio], dtype=float)
    return zetas, np.asarray(grid.frequency_ratios, dtype=float)


def _check_sensitivity_work(
    grid: SensitivityGrid, zetas: int, ratios: int, command: PiecewiseCommand, max_samples: int
) -> None:
    """Bound the curve's size (as every returned array) and its work."""
    field = "sensitivity.frequency_ratios" if grid.explicit else "sensitivity.count"
    if ratios * zetas > max_samples:
        raise InvalidParameter(field, ratios * zetas, f"at most {max_samples} (frequency, damping) points")
    breakpoints = command.end_index() + 1
    if ratios * zetas * breakpoints > MAX_SENSITIVITY_WORK:
        raise InvalidParameter(
            field,
            ratios,
            f"{ratios} ratios x {zetas} damping ratios x {breakpoints} breakpoints exceed "
            f"{MAX_SENSITIVITY_WORK:.0e}: ask fewer ratios or a longer sample_period_s",
        )


def reference_wording(problem: Problem) -> str:
    """What ``Problem.rigid_reference`` is, in words."""
    if problem.acceleration_limit is None:
        return "the unshaped step" if problem.rest_to_rest else "the unshaped velocity step"
    if not problem.rest_to_rest:
        return "the rigid ramp to the target velocity at the acceleration limit (jerk limits ignored)"
    reference = problem.rigid_reference
    cruise = " with a cruise at limits.max_velocity" if reference.time_s.size == 4 else " (bang-bang)"
    return f"the rigid time-optimal move at the acceleration limit{cruise} (jerk limits ignored)"


def percentage_vibration(
    problem: Problem,
    amplitude: NDArray[np.float64],
    ratios: NDArray[np.float64],
    zetas: NDArray[np.float64],
    natural_frequency_rad_s: float | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """V = 100 x residual amplitude / the reference's residual envelope at the same true mode (one row
    per damping ratio), and that envelope (on the unit-gain mode: times |G(0)| in the load's units). The
    ratios are about ``natural_frequency_rad_s`` (default: the plant's first mode)."""
    omega = natural_frequency_rad_s or problem.plant.modes()[0].natural_frequency_rad_s
    w = np.repeat(ratios[None, :] * omega, zetas.size, axis=0)
    z = np.repeat(zetas[:, None], ratios.size, axis=1)
    derivative = 0 if problem.rest_to_rest else 1
    envelope = residual_envelope(problem.rigid_reference, w.ravel(), z.ravel(), derivative).reshape(w.shape)
    if not np.all(envelope > 0.0):  # underflow: a move or a limit too small for double precision here
        raise InvalidParameter(
            problem.move_field, problem.move, "too small for its reference residual to be representable"
        )
    return 100.0 * amplitude / envelope, envelope


def nominal_percentage_vibration(problem: Problem, command: PiecewiseCommand) -> float | None:
    """V at the plant's first mode as modelled (ratio 1, its damping ratio); None without a mode."""
    modes = problem.plant.modes()
    if not modes:
        return None
    ratio, zeta = np.array([1.0]), np.array([modes[0].damping_ratio])
    try:
        amplitude = sensitivity(command, modes[0].natural_frequency_rad_s, ratio, zeta, problem.rest_to_rest).amplitude
    except InvalidParameter:
        return None  # round-off would spoil it (the simulation accepted the command on its own scale)
    return float(percentage_vibration(problem, amplitude, ratio, zeta)[0][0, 0])


def sensitivity_curve(
    problem: Problem,
    command: PiecewiseCommand,
    ratios: NDArray[np.float64],
    zetas: NDArray[np.float64],
    rows: NDArray[np.float64] | None = None,
) -> SensitivityCurve:
    """Percentage vibration versus f_n / f_n,e around the plant's first mode (exact free state, one dot
    product per frequency; models.sensitivity), from the residual fractions of the move ``rows`` when a
    family gives them (one per damping ratio)."""
    quantity, scale = move_scale(command, problem.rest_to_rest)
    if rows is None:
        mode = problem.plant.modes()[0]
        amplitude = sensitivity(command, mode.natural_frequency_rad_s, ratios, zetas, problem.rest_to_rest).amplitude
        rows = amplitude / (scale if scale > 0 else 1.0)
    else:
        amplitude = rows * (scale if scale > 0 else 1.0)
    percent, envelope = percentage_vibration(problem, amplitude, ratios, zetas)
    gain = problem.plant.load_move(1.0)  # the mode model moves with the motor: the load's units
    amplitude, envelope = gain * amplitude, gain * envelope
    band = band_below(ratios, percent[0], 100.0 * BAND_LEVEL)
    several = zetas.size > 1
    return SensitivityCurve(
        frequency_ratio=ratios,
        percentage_vibration=percent[0],
        reference_amplitude=envelope[0],
        reference=reference_wording(problem),
        residual_amplitude=amplitude[0],
        residual_vibration=rows[0],
        quantity=quantity,
        damping_ratio=zetas,
        percentage_vibration_grid=percent if several else None,
        residual_vibration_grid=rows if several else None,
        band_5_percent=band or None,
    )


# --- the answer's blocks -----------------------------------------------------------------------


def profile_arrays(command: PiecewiseCommand) -> Profile:
    return {
        "time_s": command.time_s,
        "position": command.derivative(0),
        "velocity": command.derivative(1),
        "acceleration": command.derivative(2),
        "jerk": command.derivative(3),
    }


def _load_arrays(response: Response) -> dict[str, NDArray[np.float64] | None]:
    """The simulated load's series (the ones the answer's ``load`` block shows), to check they are finite."""
    return {
        "position": response.load_position,
        "velocity": response.load_velocity,
        "acceleration": response.load_acceleration,
        "deflection": response.deflection,
        "motor_torque_nm": response.motor_torque_nm,
    }


def simulated_metrics(problem: Problem, command: PiecewiseCommand) -> MetricsReport:
    """The metrics of any command the answer shows beside the design (simulated here)."""
    return MetricsReport(
        metrics_of(problem, simulate(problem.plant, command)), nominal_percentage_vibration(problem, command)
    )
