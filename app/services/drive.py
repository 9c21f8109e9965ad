"""The drive in the loop: the ``closed_loop`` block of /v1/simulate and of every profile endpoint's answer.

The command (exactly the one the ideal-motor prediction ran: the design's sampled command, corners kept) is run
through the drive (models.servo_response); its load is measured as the ideal motor's is (models.metrics, the same
settling criteria), and the difference from the ideal prediction is stated."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.presenters import metrics_json
from app.schemas.drive import DriveIn, checked_drive
from app.schemas.family import ProfileRequest
from app.schemas.simulate import check_sample_count
from models.commands import MIN_STEP_S, PiecewiseCommand
from models.errors import InvalidParameter
from models.metrics import Metrics, metrics
from models.plants import Plant
from models.servo_response import DriveResponse, loop_of, simulate_drive
from models.servo_sampled import sample_count
from models.simulation import Response, simulate
from optim.problem import Problem
from optim.results import MetricsReport
from optim.synthesis import Result

SAMPLE_CAP_FIELD = "drive.sample_period_s"  # the field a sampled drive's sample cap names


@dataclass(frozen=True)
class Criteria:
    """The settling criteria the ideal prediction was measured with (models.metrics.metrics' arguments)."""

    position_tolerance: float
    settling_window: float | None
    vibration_window: float | None
    vibration_fraction: float | None

    @classmethod
    def of(cls, problem: Problem) -> Criteria:
        """A design's: optim.synthesis.metrics_of's criteria."""
        return cls(problem.settling.position_tolerance, None, problem.vibration_window, None)


def refuse_a_second_drive(body: ProfileRequest) -> None:
    """A ``drive`` beside a closed_loop plant, whose prediction is already through its drive: a 422 on ``drive``."""
    if body.drive is not None and body.plant.kind == "closed_loop":
        raise InvalidParameter(
            "drive", "given", "the plant is a closed_loop, already through its drive: give drive with its mechanics"
        )


def design_through_drive(
    drive_in: DriveIn, problem: Problem, result: Result, reference: ReferenceResiduals | None = None
) -> dict[str, Any]:
    """A design's ``closed_loop`` block: its command through the drive, measured with the problem's criteria, its
    V over the problem's unshaped rigid command through the same drive (``reference``: that command's residuals
    through it, computed once for several designs; default: computed here)."""
    if reference is None:
        reference = reference_residuals(drive_in, problem)
    return closed_loop_block(
        drive_in,
        problem.plant,
        result.command,
        result.response,
        result.metrics,
        Criteria.of(problem),
        problem.max_samples,
        reference,
    )


@dataclass(frozen=True)
class ReferenceResiduals:
    """The unshaped rigid command's residuals through the drive (V's reference); None where it has none."""

    position: float | None
    velocity: float | None


def reference_residuals(drive_in: DriveIn, problem: Problem) -> ReferenceResiduals:
    """The residuals of ``problem.rigid_reference`` through the drive: None where it cannot be run (a sampled
    drive that would need more than the sample cap for it; a reference the simulation cannot represent, such as
    a velocity step beside a slow pole) or leaves none. The reference is the problem's, never the user's input:
    its failure leaves V unknown (null), not the answer."""
    drive = checked_drive(drive_in, problem.plant)
    loop_of(problem.plant, drive)  # the drive's own errors (unstable, ...) are the request's
    command = problem.rigid_reference
    if drive.sample_period_s is not None and sample_count(command, drive.sample_period_s) > problem.max_samples:
        return ReferenceResiduals(None, None)
    try:
        run = simulate_drive(problem.plant, drive, command)
        base = metrics(run.load, problem.settling.position_tolerance, free_from=run.free_from)
    except InvalidParameter:
        return ReferenceResiduals(None, None)
    return ReferenceResiduals(
        base.residual_amplitude if base.residual_amplitude > 0.0 else None,
        base.residual_velocity_amplitude if base.residual_velocity_amplitude > 0.0 else None,
    )


def closed_loop_block(
    drive_in: DriveIn,
    plant: Plant,
    command: PiecewiseCommand,
    ideal: Response,
    ideal_metrics: Metrics,
    how: Criteria,
    max_samples: int,
    reference: ReferenceResiduals | None = None,
) -> dict[str, Any]:
    """The ``closed_loop`` block (app.schemas.simulate.ClosedLoopOut), JSON-ready apart from numpy arrays; a
    sampled drive's at its samples, within ``max_samples``. With ``reference`` (``reference_residuals``) its
    percentage vibration: the residual through the drive over the unshaped rigid command's through it."""
    drive = checked_drive(drive_in, plant)
    if drive.sample_period_s is not None:
        check_sample_count(SAMPLE_CAP_FIELD, sample_count(command, drive.sample_period_s), max_samples)
    run = simulate_drive(plant, drive, command)
    closed = metrics(
        run.load,
        how.position_tolerance,
        how.settling_window,
        how.vibration_window,
        how.vibration_fraction,
        run.free_from,
    )
    # the command's peaks (a sampled run's load Response holds the command at the samples only)
    closed = dataclasses.replace(
        closed,
        peak_velocity=ideal_metrics.peak_velocity,
        peak_acceleration=ideal_metrics.peak_acceleration,
        peak_jerk=ideal_metrics.peak_jerk,
        peak_motor_torque_nm=float(np.max(np.abs(run.torque_nm))),  # K_T i (the stand-in load plant has none)
    )
    settle, settle_ideal = closed.settling.time_s, ideal_metrics.settling.time_s
    return {
        "motor": {
            "time_s": run.time_s,
            "position": run.motor_position,
            "velocity": run.motor_velocity,
            "acceleration": run.motor_acceleration,
            "torque_nm": run.torque_nm,
            "current_a": run.current_a,
            "voltage_v": run.voltage_v,
        },
        "load": {
            "time_s": run.time_s,
            "position": run.load.load_position,
            "velocity": run.load.load_velocity,
            "acceleration": run.load.load_acceleration,
        },
        "tracking_error": run.tracking_error,
        "metrics": metrics_json(MetricsReport(closed, _percentage(closed, reference))),
        "saturated": run.saturated,
        "saturation": [vars(s) for s in run.saturation],
        "simulation": run.simulation,
        "simulation_note": run.note,
        "gains": {
            "position_kp_per_s": drive.position_kp_per_s,
            "velocity_kp": drive.velocity.kp,
            "velocity_ki": drive.velocity.ki,
            "current_kp": None if drive.current is None else drive.current.kp,
            "current_ki": None if drive.current is None else drive.current.ki,
            "sample_period_s": drive.sample_period_s,
        },
        "modes": [mode.as_dict() for mode in run.modes],
        "difference": {
            "load_position_max_abs": float(np.max(np.abs(run.load.load_position - _ideal_at(ideal, run)))),
            "residual_amplitude_ratio": (
                closed.residual_amplitude / ideal_metrics.residual_amplitude
                if ideal_metrics.residual_amplitude > 0.0
                else None
            ),
            "settling_time_change_s": None if settle is None or settle_ideal is None else settle - settle_ideal,
        },
    }


def _ideal_at(ideal: Response, run: DriveResponse) -> NDArray[np.float64]:
    """The ideal motor's load at the run's instants: its own samples; a limited run's, which go on past the
    command's end on breakpoints of the same command (simulated again on them); or a sampled drive's uniform
    instants (simulated again on the command resampled there, models.commands.PiecewiseCommand.resampled, whose
    sample count the sample cap bounds)."""
    time_s = run.time_s
    if time_s.size == ideal.time_s.size and np.array_equal(time_s, ideal.time_s):
        return ideal.load_position
    if run.simulation == "limited":
        return simulate(ideal.plant, run.load.command).load_position
    period = float(time_s[1] - time_s[0]) if time_s.size > 1 else 1.0
    finer = ideal.command.resampled(period, float(time_s[-1]))
    load = simulate(ideal.plant, finer).load_position
    nearest = np.clip(np.searchsorted(finer.time_s, time_s - MIN_STEP_S), 0, finer.time_s.size - 1)
    return load[nearest]


def _percentage(closed: Metrics, reference: ReferenceResiduals | None) -> float | None:
    """V through the drive: 100 x the load's residual over the unshaped rigid command's, both through the drive
    (position residuals at rest, velocity residuals for rest-to-velocity: the reference is the same kind of move);
    None without a reference residual."""
    if reference is None:
        return None
    moving = closed.settling.quantity == "velocity"
    theirs = reference.velocity if moving else reference.position
    ours = closed.residual_velocity_amplitude if moving else closed.residual_amplitude
    return None if theirs is None else 100.0 * ours / theirs
