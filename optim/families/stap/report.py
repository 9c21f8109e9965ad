"""What the STAP family says of a design: its ``design`` block (the ramp, the rule that chose it, the torque limit,
the candidates and the optimiser's run), completed after sampling with the simulated residual (optim.results
blocks)."""

from __future__ import annotations

from dataclasses import dataclass

from optim.families import stap as S
from optim.family import SolverSummary
from optim.results import Block


@dataclass(frozen=True)
class TorqueLimitReport(Block):
    """The acceleration limit that keeps the motor torque within max_torque_nm (eqs. 19, 57-59), and the exact
    torque peak of the design."""

    peak_torque_nm: float | None
    lowered_acceleration_limit: float | None
    max_torque_nm: float
    nodal_acceleration_limit: float
    nodal_min_acceleration_time_s: float
    inertia_ratio: float
    coefficient: float
    load_acceleration_oscillation: float
    torque_overshoot: float
    worst_frequency_ratio: float
    factor: float
    acceleration_limit: float


@dataclass(frozen=True)
class ClosedFormStart(Block):
    """The closed-form design the optimiser started from."""

    acceleration_time_s: float
    jerk_time_s: float
    nominal_residual: float
    grid_worst_residual: float | None


@dataclass(frozen=True)
class OptimizationReport(Block):
    """The IPOPT run over (t_a, t_j) (method ``optimized``)."""

    objective: str
    selection: str
    nominal_residual: float
    grid_worst_residual: float | None
    closed_form: ClosedFormStart
    acceleration_time_bounds_s: tuple[float, float]
    jerk_time_floor_s: float
    torque_constrained: bool
    solver: SolverSummary


@dataclass(frozen=True)
class StapReport(Block):
    """The ``design`` block."""

    method: str
    move: str
    rule: str
    auto_rule: str
    estimated_frequency_hz: float
    target_velocity: float
    acceleration_time_s: float
    jerk_time_s: float
    constant_acceleration_time_s: float
    min_acceleration_time_s: float | None
    peak_acceleration: float
    peak_jerk: float | None
    shape: str
    k_j: int | None
    delta: int | None
    jerk_periods: float
    acceleration_time_periods: float
    dimensionless_jerk_time: float
    acceleration_limit: float | None
    limit_reached: bool
    torque_limit: TorqueLimitReport | None
    load_acceleration_oscillation: float
    frequency_uncertainty: float
    residual_tolerance: float
    band_worst_residual: float
    candidates: tuple[S.ZeroVibrationCandidate, ...] | None
    candidates_truncated: bool | None
    k_j_max: int | None
    delta_f: int | None
    paper_k_j_max: int | None
    paper_delta_f: int | None
    auto_steps: tuple[S.AutoStep, ...] | None
    displacement: float | None
    cruise_velocity: float | None
    cruise_time_s: float | None
    duration_s: float
    total_time_s: float
    requested_velocity: float | None
    velocity_lowered: bool | None
    optimization: OptimizationReport | None
    residual_vibration: float | None = None  # after sampling (optim.results.Finish)


def torque_report(closed: S.StapDesign, speed: float) -> TorqueLimitReport | None:
    torque = closed.torque
    if torque is None:
        return None
    return TorqueLimitReport(
        peak_torque_nm=closed.peak_torque_nm,
        lowered_acceleration_limit=closed.torque_lowered_acceleration,
        max_torque_nm=torque.max_torque_nm,
        nodal_acceleration_limit=torque.nodal_acceleration_limit,
        nodal_min_acceleration_time_s=speed / torque.nodal_acceleration_limit,
        inertia_ratio=torque.inertia_ratio,
        coefficient=torque.coefficient,
        load_acceleration_oscillation=torque.load_acceleration_oscillation,
        torque_overshoot=torque.torque_overshoot,
        worst_frequency_ratio=torque.worst_frequency_ratio,
        factor=torque.factor,
        acceleration_limit=torque.acceleration_limit,
    )


def optimization_report(optimized: S.OptimizedDesign, torque_limited: bool) -> OptimizationReport:
    return OptimizationReport(
        objective=optimized.objective,
        selection=optimized.selection,
        nominal_residual=optimized.nominal_residual,
        grid_worst_residual=optimized.grid_worst_residual,
        closed_form=ClosedFormStart(
            acceleration_time_s=optimized.start.acceleration_time_s,
            jerk_time_s=optimized.start.jerk_time_s,
            nominal_residual=optimized.start_nominal_residual,
            grid_worst_residual=optimized.start_grid_worst_residual,
        ),
        acceleration_time_bounds_s=optimized.acceleration_time_bounds_s,
        jerk_time_floor_s=optimized.jerk_time_floor_s,
        torque_constrained=torque_limited,
        solver=SolverSummary.of(optimized.solver, optimized.solves),
    )
