"""A program's moves laid end to end: each axis's command over the whole cycle, what its load does, and the
residual vibration at every stop (optim.programs).

An axis without a plant table is time-invariant: its load is models.simulation's exact response to the whole
cycle's command, and a stop's residual is the free vibration left at the stop's end (the command rests there
until the next move), carried over from earlier moves included. An axis with a table is simulated on its true
plant, the mode following the coordinate at every instant (models.varying_mode, DOP853 at 1e-12): an
independent check of designs made for the plant at each stop.
"""

from __future__ import annotations

import bisect
import contextlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.commands import MIN_STEP_S, PiecewiseCommand
from models.errors import DomainError, InvalidParameter, SolverFailed
from models.plants import Plant
from models.simulation import simulate
from models.varying_mode import deflection, free_amplitude
from optim.problem import DEFAULT_SAMPLES, MIN_MOVE, TAIL_PERIODS, Problem, nice_period
from optim.programs.moves import MoveDesign, move_problem, plant_of
from optim.programs.settling import StopCriteria, TrueMotion, settled_s
from optim.programs.tables import mode_function, modes_at
from optim.programs.types import Program
from optim.solver import SolverReport

Array = NDArray[np.float64]


@dataclass(frozen=True)
class AxisCycle:
    """One axis over the cycle: its exact command, its samples (profile and load), and its residual at each stop
    (load units), by ``method`` ("exact": the time-invariant closed form; "varying": the true plant integrated)."""

    name: str
    command: PiecewiseCommand
    time_s: Array
    profile: Array  # (4, samples): position, velocity, acceleration, jerk
    load: Array  # (3, samples): position, velocity, acceleration
    stop_residuals: Array  # one per move, at its end
    method: str
    period_s: float  # the samples' grid (the stops' ends added to it)
    settling_s: tuple[float | None, ...] | None = None  # "varying": per move, its settling on the true plant


def move_starts(program: Program, designs: Sequence[MoveDesign]) -> Array:
    """Each move's start in the cycle, and the cycle's end last: the moves and their dwells end to end."""
    spans = [d.duration_s + m.dwell_s for d, m in zip(designs, program.moves, strict=True)]
    return np.concatenate(([0.0], np.cumsum(spans)))


def cycle_command(program: Program, designs: Sequence[MoveDesign], i: int, starts: Array) -> PiecewiseCommand:
    """Axis i's command over the cycle: each move's command where the axis moves, rest between, a breakpoint at
    every move's start and end (where the stops' residuals are read)."""
    pieces = [(float(starts[k]), c) for k, d in enumerate(designs) if (c := d.axes[i].command) is not None]
    degree = max((c.degree for _, c in pieces), default=0)
    orders = min((c.continuous_orders for _, c in pieces), default=0)
    times: list[Array] = []
    rows: list[Array] = []
    position = program.start[i]
    marks = sorted({*starts.tolist(), *(float(s) + d.duration_s for s, d in zip(starts, designs, strict=False))})
    cursor = 0
    for offset, command in pieces:
        for mark in marks[cursor:]:  # the rests before this piece
            if mark >= offset - MIN_STEP_S:
                break
            times.append(np.array([mark]))
            rows.append(_rest(position, degree))
            cursor += 1
        derivatives = np.zeros((degree + 1, command.time_s.size))
        derivatives[: command.degree + 1] = command.derivatives
        times.append(command.time_s + offset)
        rows.append(derivatives)
        position = float(command.derivatives[0, -1])
        while cursor < len(marks) and marks[cursor] <= offset + float(command.time_s[-1]) + MIN_STEP_S:
            cursor += 1
    for mark in marks[cursor:]:
        times.append(np.array([mark]))
        rows.append(_rest(position, degree))
    t = np.concatenate(times)
    d = np.concatenate(rows, axis=1)
    keep = np.append(np.diff(t) > MIN_STEP_S, True)  # of two breakpoints at one instant, the later's values
    return PiecewiseCommand(t[keep], d[:, keep], orders)


def _rest(position: float, degree: int) -> Array:
    column = np.zeros((degree + 1, 1))
    column[0, 0] = position
    return column


def _grid(program: Program, end_s: float, tail_s: float) -> tuple[Array, float]:
    room = max(2, program.max_samples // len(program.axes) - len(program.moves) - 1)  # the stops' ends added
    period = program.sample_period_s or nice_period(end_s + tail_s, min(DEFAULT_SAMPLES, room))
    count = int((end_s + tail_s) / period) + 1
    if (count + len(program.moves)) * len(program.axes) > program.max_samples:
        raise InvalidParameter(
            "sample_period_s",
            period,
            f"{count} samples for each of {len(program.axes)} axes exceed the cap of {program.max_samples}",
        )
    return np.arange(count, dtype=float) * period, period


def axis_cycle(
    program: Program, designs: Sequence[MoveDesign], i: int, starts: Array, tail_s: float, samples: bool = True
) -> AxisCycle:
    """Axis i's command, samples and stop residuals over the cycle (see the module's docstring); without
    ``samples`` the stops' residuals only (the recipes' rows: no profile or load)."""
    axis = program.axes[i]
    command = cycle_command(program, designs, i, starts)
    stop_ends = np.array([float(s) + d.duration_s for s, d in zip(starts, designs, strict=False)])
    grid, period = _grid(program, float(starts[-1]), tail_s) if samples else (np.zeros(1), 0.0)
    t = np.unique(np.concatenate((grid, stop_ends)))
    profile = command.evaluate_at_instants(t, 4) if samples else np.zeros((4, 0))
    if axis.table is None:
        residuals = np.array([stop_residual(axis.plant, command, float(end)) for end in stop_ends])
        if not samples:
            return AxisCycle(axis.name, command, t[:0], profile, np.zeros((3, 0)), residuals, "exact", period)
        sampled = PiecewiseCommand(t, command.evaluate_at_instants(t, command.degree + 1), command.continuous_orders)
        response = simulate(axis.plant, sampled)
        load = np.vstack((response.load_position, response.load_velocity, response.load_acceleration))
        return AxisCycle(axis.name, command, t, profile, load, residuals, "exact", period)
    table = axis.table
    mode_at_coordinate = mode_function(table)
    if table.coordinate in program.names:
        coordinate = cycle_command(program, designs, program.axis_index(table.coordinate), starts)
        position, breaks = position_function(coordinate), coordinate.time_s
        at_samples = coordinate.evaluate_at_instants(t, 1)[0]  # (the integration's position, vectorised)
    else:  # a parameter: constant over each move (and the dwell after it), changing where the next move starts
        values = [float(program.parameter(k, table.coordinate) or 0.0) for k in range(len(program.moves))]
        bounds = starts[1:-1].tolist()
        position, breaks = (lambda time: values[bisect.bisect_right(bounds, time)]), starts
        at_samples = np.asarray(values)[np.searchsorted(bounds, t, side="right")]
    omega, zeta = modes_at(table, at_samples)  # the mode at every sample (t holds every stop's end)

    def mode_of_time(time: float) -> tuple[float, float]:
        return mode_at_coordinate(position(time))

    still = tuple((float(end), float(start)) for end, start in zip(stop_ends, starts[1:], strict=True) if start > end)
    try:
        solved = deflection(command, mode_of_time, t, breaks, (*still, (float(starts[-1]), float(t[-1]))))
    except ArithmeticError as exc:  # DOP853 failed (it does not on a mode and a piecewise-polynomial command)
        raise SolverFailed(SolverReport("integration_failed", 0, 0.0), str(exc)) from None
    at = np.searchsorted(t, stop_ends)
    residuals = free_amplitude(solved.deflection[at], solved.rate[at], omega[at], zeta[at])
    if not samples:
        return AxisCycle(axis.name, command, t[:0], profile, np.zeros((3, 0)), residuals, "varying", period)
    accel = -2.0 * zeta * omega * solved.rate - omega * omega * solved.deflection
    load = np.vstack((profile[0] + solved.deflection, profile[1] + solved.rate, accel))
    motion = TrueMotion.of(t, profile, solved.deflection, solved.rate, omega, zeta)
    settling = tuple(
        _true_settling(program, designs, i, k, motion, float(starts[k]), float(stop_ends[k]), float(residuals[k]))
        for k in range(len(designs))
    )
    return AxisCycle(axis.name, command, t, profile, load, residuals, "varying", period, settling)


def _true_settling(
    program: Program,
    designs: Sequence[MoveDesign],
    i: int,
    k: int,
    motion: TrueMotion,
    start_s: float,
    end_s: float,
    residual: float,
) -> float | None:
    """Axis i's settling in move k on its true plant (optim.programs.settling), with the criteria of its problem
    on the plant at the stop; None where it does not move."""
    target = program.moves[k].target[i]
    delta = target - program.stop(k)[i]
    if delta == 0.0 or designs[k].axes[i].command is None:
        return None
    first, end = np.searchsorted(motion.time_s, [start_s, end_s], side="left")
    during = slice(int(first), int(end) + 1)  # (end_s is a sample: the stop)
    excursion = float(np.max(np.abs(motion.profile[0][during] + motion.deflection[during] - program.stop(k)[i])))
    plant = plant_of(program, i, k)[0]
    problem = move_problem(program, plant, delta, program.axes[i].limits)
    band = program.settling.position_tolerance * max(abs(delta), excursion)
    at = int(np.searchsorted(motion.time_s, end_s))  # the mode at the stop, as the integration has it
    criteria = StopCriteria(band, problem.vibration_window, float(motion.omega_rad_s[at]), float(motion.zeta[at]))
    return settled_s(motion, start_s, end_s, target, residual, criteria)


def stop_residual(plant: Plant, command: PiecewiseCommand, end_s: float) -> float:
    """The load's free vibration at ``end_s``, where the command rests (a stop): the residual amplitude of the
    command up to there, the rest of the cycle cut off (a breakpoint where the next move starts at once carries
    that move's first jump, which the free state there includes)."""
    keep = command.time_s < end_s - MIN_STEP_S
    position = float(command.evaluate_at_instants(np.array([end_s]), 1)[0, 0])
    times = np.append(command.time_s[keep], end_s)
    derivatives = np.hstack((command.derivatives[:, keep], _rest(position, command.degree)))
    response = simulate(plant, PiecewiseCommand(times, derivatives, command.continuous_orders))
    return float(np.sum(response.free_amplitudes(times.size - 1, 0)[response.modal.oscillatory]))


def position_function(command: PiecewiseCommand) -> Callable[[float], float]:
    """t -> the command's position, in plain float arithmetic (right-continuous, as ``evaluate``)."""
    times = command.time_s.tolist()
    scaled = (command.derivatives / np.array([math.factorial(n) for n in range(command.degree + 1)])[:, None]).T
    rows: list[list[float]] = [row[::-1] for row in scaled.tolist()]

    def position(t: float) -> float:
        k = bisect.bisect_right(times, t) - 1
        if k < 0:
            return float(rows[0][-1])
        tau = t - times[k]
        out = 0.0
        for c in rows[k]:
            out = out * tau + c
        return out

    return position


def tail_s(program: Program, designs: Sequence[MoveDesign]) -> float:
    """How long the samples run past the cycle: TAIL_PERIODS periods of the slowest mode at the last stop."""
    periods = [m.natural_period_s for a in designs[-1].axes for m in a.plant.modes()]
    return TAIL_PERIODS * max(periods, default=0.0)


MAX_VARYING_PERIODS = 20_000  # periods of a table's fastest mode integrated per cycle, at most (about 10 s)


def check_varying_work(program: Program, durations_s: Sequence[float]) -> None:
    """Bound the true plant's integration in units of work: the moves' durations (dwells are carried in closed
    form) times the fastest frequency of any table, at most MAX_VARYING_PERIODS; else a 422 naming ``moves``."""
    tables = [a.table for a in program.axes if a.table is not None]
    if not tables:
        return
    fastest = max(p.plant.modes()[0].natural_frequency_hz for table in tables for p in table.points)
    periods = sum(durations_s) * fastest * len(tables)
    if periods > MAX_VARYING_PERIODS:
        raise InvalidParameter(
            "moves",
            len(program.moves),
            f"the moves last {periods:.3g} periods of the tables' modes in all: the true plant's simulation takes at "
            f"most {MAX_VARYING_PERIODS} (fewer or shorter moves)",
        )


def cycle(program: Program, designs: Sequence[MoveDesign], samples: bool = True) -> tuple[Array, tuple[AxisCycle, ...]]:
    """The moves end to end: when each starts (and the cycle's end), and each axis's ``AxisCycle`` (``samples``:
    with its profile and load; without, the stops' residuals only)."""
    check_varying_work(program, [d.duration_s for d in designs])
    starts = move_starts(program, designs)
    tail = tail_s(program, designs)
    return starts, tuple(axis_cycle(program, designs, i, starts, tail, samples) for i in range(len(program.axes)))


def check_before_designs(program: Program) -> None:
    """The bounds of ``cycle`` checked before any design, on a floor of each move's duration (every axis's rigid
    minimum time within its limits, Ruckig's: no design is shorter): the true plant's periods and, with a
    sample_period_s, the samples. A program refused here would be refused after its designs too."""
    floors = [move_floor_s(program, k) for k in range(len(program.moves))]
    check_varying_work(program, floors)
    if program.sample_period_s is not None:
        span = sum(floors) + sum(m.dwell_s for m in program.moves)
        _grid(program, span, 0.0)


def move_floor_s(program: Program, k: int) -> float:
    """No design of move k is shorter: the longest of its axes' rigid minimum times (0 where one is not known)."""
    start, target = program.stop(k), program.moves[k].target
    floors = [0.0]
    for axis, a, b in zip(program.axes, start, target, strict=True):
        if abs(b - a) >= MIN_MOVE:
            with contextlib.suppress(DomainError):  # (a bad move is named by its design, with its field)
                floors.append(Problem(axis.plant, b - a, limits=axis.limits).rigid_floor_s)
    return max(floors)
