"""A machine program designed and checked: every move's design (optim.programs.moves), the cycle laid end to end
and simulated (optim.programs.cycle), and per move its duration, its settling and each axis's metrics.

``design_moves`` and ``assemble`` are separate so that a caller can design the moves where it likes (a pool, Dask:
each move starts from rest at a stop, so they are independent) and assemble them here; ``solve_program`` does both
in the calling process.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from optim.problem import TAIL_PERIODS, nice_period
from optim.programs.cycle import AxisCycle, check_before_designs, cycle
from optim.programs.moves import MoveDesign, move_problem, moving_axes, plant_of
from optim.programs.types import Program, check_axes, check_moves
from optim.programs.varying import VaryingFit, design_varying
from optim.results import MetricsReport
from optim.synthesis import limit_violations, simulated_metrics

Array = NDArray[np.float64]


RINGING = 1e-6  # a still stop whose residual is above this fraction of the axis's largest move: named in a warning


@dataclass(frozen=True)
class AxisOutcome:
    """One axis in one move: its design's metrics (simulated on the plant it was designed for, from rest at the
    stop), the residual at the stop in the cycle (carried vibration included; the true plant for a table), that
    residual over the axis's move, and when its load settles (the metrics', or on the true plant for a table:
    optim.programs.settling; None where it does not move or never settles)."""

    metrics: MetricsReport | None
    stop_residual_amplitude: float
    stop_residual_fraction: float | None
    settling_time_s: float | None = None


@dataclass(frozen=True)
class MoveOutcome:
    design: MoveDesign
    start_s: float
    settling_time_s: float | None
    axes: tuple[AxisOutcome, ...]
    varying: VaryingFit | None = None


@dataclass(frozen=True)
class ProgramResult:
    program: Program
    cycle_time_s: float
    moves: tuple[MoveOutcome, ...]
    axes: tuple[AxisCycle, ...]
    warnings: tuple[str, ...]


def check_program(program: Program) -> None:
    """What the core refuses before designing (a 422 naming the field): see types.check_axes and check_moves, and
    each table's range holding the positions its coordinate goes to."""
    check_axes(program.axes, program.parameter_names)
    check_moves(program)
    for i, axis in enumerate(program.axes):
        if axis.limits.max_torque_nm is not None:
            raise InvalidParameter(
                f"axes[{i}].limits.max_torque_nm",
                axis.limits.max_torque_nm,
                "programs take velocity, acceleration and jerk limits (a torque limit is not projected on a path)",
            )
        if axis.table is None:
            continue
        low, high = axis.table.low, axis.table.high
        if axis.table.coordinate not in program.names:
            _check_parameter(program, i, axis.table.coordinate, low, high)
            continue
        j = program.axis_index(axis.table.coordinate)
        name = program.axes[j].name
        for field, value in (
            ("start", program.start[j]),
            *((f"moves[{k}].target", m.target[j]) for k, m in enumerate(program.moves)),
        ):
            if not low <= value <= high:
                raise InvalidParameter(
                    f"{field}.{name}",
                    value,
                    f"is outside axes[{i}].plant_table's range [{low:g}, {high:g}] (the "
                    f"plant of axis {axis.name} is known there only)",
                )
    check_before_designs(program)  # the work's bounds, on the moves' floors


def _check_parameter(program: Program, i: int, name: str, low: float, high: float) -> None:
    """A parameter coordinate: known in every move (given at the start or by a move before), each value given within
    the table's range."""
    given = [("parameters", dict(program.parameters).get(name))]
    given += [(f"moves[{k}].parameters", dict(m.parameters).get(name)) for k, m in enumerate(program.moves)]
    for where, value in given:
        if value is not None and not low <= value <= high:
            raise InvalidParameter(
                f"{where}.{name}", value, f"is outside axes[{i}].plant_table's range [{low:g}, {high:g}]"
            )
    if program.parameter(0, name) is None:
        raise InvalidParameter(
            f"parameters.{name}", None, f"axes[{i}].plant_table needs its value from the first move on (give it here)"
        )


def design_one(program: Program, k: int) -> tuple[MoveDesign, VaryingFit | None]:
    """Move k's design with its moving axes' metrics (module-level: a worker process or a Dask worker runs it). The
    metrics are simulated from rest at the stop, nothing of the other moves: computed here, where the moves are
    designed in parallel, rather than in ``assemble`` after them (bench/programs.py's 20 moves: assemble took 0.08 s
    with them, 0.02 without)."""
    design, fit = design_varying(program, k)
    reports = tuple(None if a.command is None else _metrics(program, k, i, design) for i, a in enumerate(design.axes))
    return replace(design, metrics=reports), fit


def heaviest_first(program: Program) -> list[int]:
    """The moves in the order a pool should start them: the most modes cancelled by one design first (a straight
    line's path design cancels every moving axis's modes at once: 0.4 s a move on average on bench/programs.py, its
    other moves 0.1), so that the longest designs do not start last (longest first, the classic greedy schedule);
    ties in program order. The answer does not depend on it (each move is designed alone)."""

    def modes(k: int) -> int:
        counts = [len(program.axes[i].plant.modes()) for i in moving_axes(program, k)]
        return sum(counts) if program.moves[k].coordination == "straight_line" else max(counts, default=0)

    return sorted(range(len(program.moves)), key=lambda k: -modes(k))


def design_moves(program: Program) -> tuple[tuple[MoveDesign, VaryingFit | None], ...]:
    return tuple(design_one(program, k) for k in range(len(program.moves)))


def assemble(program: Program, designed: Sequence[tuple[MoveDesign, VaryingFit | None]]) -> ProgramResult:
    """The cycle of the designed moves: the commands end to end, simulated, and each move's figures."""
    designs = [d for d, _ in designed]
    starts, axes = cycle(program, designs)
    largest = [  # each axis's largest move in the program: the scale of a residual where it stays
        max(abs(m.target[i] - program.stop(k)[i]) for k, m in enumerate(program.moves))
        for i in range(len(program.axes))
    ]
    warnings: list[str] = []
    moves = []
    for k, design in enumerate(designs):
        outcomes = []
        settling: list[float | None] = []
        for i, axis_move in enumerate(design.axes):
            delta = abs(program.moves[k].target[i] - program.stop(k)[i])
            report, settled_here = None, None
            if axis_move.command is not None:
                report = _metrics(program, k, i, design) if design.metrics is None else design.metrics[i]
                assert report is not None  # (design_one computes one for every axis that moves)
                true = axes[i].settling_s  # on the true plant, where it changes during the moves
                settled_here = report.metrics.settling.time_s if true is None else true[k]
                settling.append(settled_here)
                violations = limit_violations(program.axes[i].limits, report.metrics)
                if violations:  # a defect: every design is within its limits (the pipeline checks each)
                    raise AssertionError(f"moves[{k}] axis {axis_move.axis}: {'; '.join(violations)}")
            residual = float(axes[i].stop_residuals[k])
            outcomes.append(AxisOutcome(report, residual, residual / delta if delta else None, settled_here))
        still = program.moves[k].still_at_stop
        settled = None if any(s is None for s in settling) else max((s for s in settling if s is not None), default=0.0)
        fit = designed[k][1]
        moves.append(MoveOutcome(design, float(starts[k]), settled if still else None, tuple(outcomes), fit))
        warnings += [f"moves[{k}]: {w}" for w in design.warnings]
        ringing = [
            f"{a.axis} {o.stop_residual_amplitude / scale:.2g}"
            for a, o, scale in zip(design.axes, outcomes, largest, strict=True)
            if scale > 0.0 and o.stop_residual_amplitude > RINGING * scale
        ]
        if still and ringing:
            warnings.append(
                f"moves[{k}]: the load is not still at this stop ({', '.join(ringing)} of the axis's largest move): "
                "vibration carried from a stop where it need not be still, or a design that could not cancel a "
                "varying mode (above)"
            )
    return ProgramResult(program, float(starts[-1]), tuple(moves), axes, tuple(warnings))


def _metrics(program: Program, k: int, i: int, design: MoveDesign) -> MetricsReport:
    """Axis i's command in move k simulated on the plant it was designed for (for an effective mode: the plant at
    the stop), from rest at the stop, sampled as a family endpoint samples its design (settling is checked at the
    samples)."""
    axis_move = design.axes[i]
    assert axis_move.command is not None
    command = axis_move.command
    plant = plant_of(program, i, k)[0] if axis_move.effective else axis_move.plant
    problem = move_problem(program, plant, program.moves[k].target[i] - program.stop(k)[i], program.axes[i].limits)
    end = float(command.time_s[-1])
    horizon = end + TAIL_PERIODS * problem.slowest_period_s
    shifted = command.derivatives.copy()
    shifted[0] -= program.stop(k)[i]  # the move from 0, as its problem states it
    relative = PiecewiseCommand(command.time_s, shifted, command.continuous_orders)
    return simulated_metrics(problem, relative.resampled(nice_period(horizon), end_s=horizon))


def solve_program(program: Program) -> ProgramResult:
    check_program(program)
    return assemble(program, design_moves(program))
