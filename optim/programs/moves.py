"""One move of a program: every axis's command from its stop to the next (optim.programs).

- ``straight_line``: one path parameter s from 0 to the move's length L = |target - stop|; axis i follows
  stop_i + u_i s (u = (target - stop) / L), so each limit of the path is the least of the moving axes' limits
  over |u_i|, and the path's plant holds every moving axis's modes (a transfer function whose poles are theirs:
  the family cancels them all, and each axis, driven by u_i times the path's command, is left still).
- ``synchronized``: each axis its own design; the faster ones averaged with themselves delayed (a convolution with
  two half impulses, ``stretched``), so that every axis starts and arrives together. Each stretched command is a
  convex combination of the design, so it keeps its limits, and its residual at each mode is the design's times
  the two impulses' transform: zero where the design's was. The axes are designed longest rigid move first; an
  axis whose shaped rigid optimum (ZV-shaped Ruckig) is no longer than a design already made is given that, with no
  search (TimeOptimalOptions.sufficient_duration_s): it is stretched to the same end whatever its own duration.
- ``independent``: each axis its own design from the move's start; the move lasts as long as the slowest.

An axis whose plant is a table over a coordinate is designed for the plant at the stop, robust over the band
of frequencies the coordinate passes through during the move (time-optimal only); ``still_at_stop`` false gives
the rigid time-optimal move (Ruckig), nothing cancelled.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from models.commands import MIN_STEP_S, PiecewiseCommand
from models.errors import Infeasible, InvalidParameter, NotApplicable
from models.plants import ModePlant, Plant, TransferFunctionPlant
from optim.families.time_optimal.options import Robustness, TimeOptimalOptions
from optim.family import Design, SolverSummary
from optim.problem import MIN_MOVE, Limits, Problem
from optim.programs.tables import frequency_range_hz, plant_at
from optim.programs.types import Program
from optim.registry import FAMILIES
from optim.results import Block, MetricsReport
from optim.synthesis import evaluate, synthesize

SAME_TIME_RTOL = 1e-12  # an axis this close to the move's duration is not stretched
BAND_MIN_SPREAD = 1e-9  # a mode that changes less than this (relative) over the move is taken as constant


@dataclass(frozen=True)
class RigidReport(Block):
    """The design block of a move that need not leave the load still: Ruckig's rigid optimum."""

    method: str
    duration_s: float


@dataclass(frozen=True)
class PathReport(Block):
    """A straight line's path parameter: its length, each axis's share u_i and the limits projected on it."""

    length: float
    direction: dict[str, float]
    max_velocity: float | None
    max_acceleration: float | None
    max_jerk: float | None
    modes_hz: tuple[float, ...]


@dataclass(frozen=True)
class AxisMove:
    """One axis's part of a move: its command (absolute positions, time from the move's start; None: it stays),
    the plant it was designed for, the family's design block and the band designed over."""

    axis: str
    command: PiecewiseCommand | None
    plant: Plant
    summary: Block | None
    solver: SolverSummary | None
    band_hz: tuple[float, float] | None
    stretched_from_s: float | None = None  # synchronized: the design's own duration before it was stretched
    effective: bool = False  # designed for an effective mode that leaves the true, varying plant still
    design: Design | None = None  # the family's design (a nearby move's redesign starts from it)
    own: PiecewiseCommand | None = None  # the axis's own command before synchronization (absolute)
    second: Design | None = None  # a stretched axis's delayed half, where designed for a mode of its own


@dataclass(frozen=True)
class MoveDesign:
    index: int
    duration_s: float
    axes: tuple[AxisMove, ...]
    path: PathReport | None
    warnings: tuple[str, ...]
    # each axis's metrics (None where it stays), where computed beside the design (optim.programs.run.design_one)
    metrics: tuple[MetricsReport | None, ...] | None = None


def coordinate_span(program: Program, k: int, coordinate: str) -> tuple[float, float]:
    """Where the coordinate starts and ends move ``k``: an axis's positions, or a parameter's value (constant over a
    move: it changes at a stop)."""
    if coordinate not in program.names:
        value = program.parameter(k, coordinate)
        assert value is not None  # run.check_program
        return value, value
    j = program.axis_index(coordinate)
    return program.stop(k)[j], program.moves[k].target[j]


# axis -> (w rad/s, zeta) the design is made for instead; a synchronized axis that is stretched may give a second
# pair, for the delayed half of its command (each half then leaves the true plant what the other cancels)
Effective = Mapping[int, tuple[float, ...]]


@dataclass(frozen=True)
class EffectiveModePlant(ModePlant):
    """A ``mode`` whose damping ratio may be negative: the effective mode of a plant that changes during a move
    (optim.programs.varying), whose vibration the change may feed (a frequency that falls raises its amplitude). Only
    designed for, never simulated as the machine's plant."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.damping_ratio) and -1.0 < self.damping_ratio < 1.0):
            raise InvalidParameter("damping_ratio", self.damping_ratio, "an effective mode's lies in (-1, 1)")
        ModePlant(self.natural_frequency_hz, 0.0)  # the frequency's own checks


def effective_mode(omega_rad_s: float, zeta: float) -> ModePlant:
    """The plant a design is made for in place of a varying one: a ``mode``, with a negative damping ratio where
    the effective mode's is."""
    hz = omega_rad_s / (2.0 * math.pi)
    return ModePlant(hz, zeta) if zeta >= 0.0 else EffectiveModePlant(hz, zeta)


def plant_of(
    program: Program, i: int, k: int, effective: Effective | None = None
) -> tuple[Plant, tuple[float, float] | None]:
    """Axis i's plant at the end of move k, and the band of its mode's frequency over the move (None: constant);
    where ``effective`` names the axis, a mode of that frequency and damping ratio instead, and no band."""
    axis = program.axes[i]
    if effective is not None and i in effective:
        omega, zeta = effective[i][:2]
        return effective_mode(omega, zeta), None
    if axis.table is None:
        return axis.plant, None
    a, b = coordinate_span(program, k, axis.table.coordinate)
    plant = plant_at(axis.table, b)
    low, high = frequency_range_hz(axis.table, min(a, b), max(a, b))
    return plant, (low, high) if high > low * (1.0 + BAND_MIN_SPREAD) else None


def move_problem(program: Program, plant: Plant, move: float, limits: Limits) -> Problem:
    """One axis's (or a path's) move as the family's problem, with the program's settling criteria and caps."""
    return Problem(
        plant=plant,
        displacement=move,
        limits=limits,
        settling=program.settling,
        solver=program.solver,
        max_samples=program.max_samples,
    )


@contextlib.contextmanager
def named(field: str) -> Iterator[None]:
    """A design's error named by the program's field it comes from (``moves[k].target.x``: the axis's move there;
    ``moves[k]``: a straight line), its own field after it in the rule."""
    try:
        yield
    except InvalidParameter as exc:
        raise InvalidParameter(field, exc.value, f"{exc.field}: {exc.rule}" if exc.field else exc.rule) from None
    except (Infeasible, NotApplicable) as exc:
        raise type(exc)(f"{field}: {exc.reason}", field) from None


class NoNearbyDesign(ArithmeticError):
    """A design asked from a previous one's structure does not exist (a grid answer, or Newton diverged): the
    designs would not change smoothly with the mode, which optim.programs.varying relies on."""


@dataclass(frozen=True)
class Designed:
    """One design from position 0: its command (exact where the family has it), block, solver summary, warnings
    and the family's ``Design`` (None for the rigid move)."""

    command: PiecewiseCommand
    summary: Block | None
    solver: SolverSummary | None
    notes: tuple[str, ...]
    design: Design | None


def _designed(
    program: Program,
    problem: Problem,
    band: tuple[float, float] | None,
    still: bool,
    previous: Design | None = None,
    sufficient_s: float | None = None,
) -> Designed:
    """The family's design, from ``previous``'s structure where the family can (``redesign``: a nearby problem), or
    the rigid optimum where the load need not be still; ``sufficient_s``: a duration another axis sets the pace of
    (the time-optimal family stops at a command no longer: TimeOptimalOptions.sufficient_duration_s)."""
    if not still:
        lim = problem.limits
        rigid = problem.rigid_move(lim.max_velocity, lim.max_acceleration, lim.max_jerk)
        command = PiecewiseCommand.from_held_steps(
            rigid.edges_s, [*(math.copysign(1.0, problem.move) * rigid.levels), 0.0], rigid.order
        )
        return Designed(command, RigidReport("rigid_time_optimal", rigid.duration_s), None, (), None)
    family = FAMILIES[program.family]
    notes: tuple[str, ...] = ()
    if family.name == "time_optimal":
        robust = None if band is None else Robustness(frequency_range_hz=band)
        options: Any = TimeOptimalOptions(robustness=robust, sufficient_duration_s=sufficient_s)
    else:
        options = family.default_options(problem)
        if band is not None:
            notes = (
                f"{family.name} designs for the plant at the stop, not robust over the band its mode passes through "
                f"during the move ({band[0]:.6g} to {band[1]:.6g} Hz)",
            )
    redesign = getattr(family, "redesign", None)  # the design from the previous one's structure, in milliseconds
    nearby = None if previous is None or redesign is None else redesign(problem, options, previous)
    result = synthesize(family, problem, options) if nearby is None else evaluate(family, problem, nearby)
    if previous is not None and getattr(result.summary, "method", None) == "grid":  # (afresh where the structure
        raise NoNearbyDesign(f"{family.name}'s design here is a grid answer")  # changed: a grid answer's is not smooth)
    command = result.design.command if result.design.command is not None else result.run.command
    return Designed(command, result.summary, result.solver, (*notes, *result.warnings), result.design)


def _absolute(command: PiecewiseCommand, start: float, scale: float = 1.0) -> PiecewiseCommand:
    """``start + scale * command`` (a command from position 0)."""
    derivatives = command.derivatives * scale
    derivatives[0] += start
    return PiecewiseCommand(command.time_s.copy(), derivatives, command.continuous_orders)


def stretched(command: PiecewiseCommand, end_s: float, late: PiecewiseCommand | None = None) -> PiecewiseCommand:
    """(p(t) + q(t - delta)) / 2 with q = ``late`` (default p) and delta = end_s - q's end: the same move (p and q
    are moves between the same positions) ending at ``end_s``. Both halves start at rest; the result is exact
    (every breakpoint of both kept)."""
    second = command if late is None else late
    delta = end_s - float(second.time_s[-1])
    times = np.sort(np.concatenate((command.time_s, second.time_s + delta)))
    times = times[np.concatenate(([True], np.diff(times) > MIN_STEP_S))]  # a breakpoint of both halves once
    orders = max(command.degree, second.degree) + 1
    # each instant on the piece of its nearest breakpoint (t + delta - delta is t only to round-off)
    rows = 0.5 * (command.evaluate_at_instants(times, orders) + second.evaluate_at_instants(times - delta, orders))
    return PiecewiseCommand(times, rows, min(command.continuous_orders, second.continuous_orders))


def moving_axes(program: Program, k: int) -> list[int]:
    """The axes move ``k`` moves (its target differs from its stop)."""
    return [i for i, (a, b) in enumerate(zip(program.stop(k), program.moves[k].target, strict=True)) if b != a]


def design_move(
    program: Program, k: int, effective: Effective | None = None, previous: MoveDesign | None = None
) -> MoveDesign:
    """Every axis's command for move ``k`` (see the module's docstring); fields named ``moves[k]...``. With
    ``effective``, those axes are designed for the modes given; with ``previous`` (this move's design for other
    effective modes), the axes not in ``effective`` keep their designs and the others start from theirs."""
    move = program.moves[k]
    start = program.stop(k)
    deltas = [b - a for a, b in zip(start, move.target, strict=True)]
    for i, d in enumerate(deltas):
        if d != 0.0 and abs(d) < MIN_MOVE:
            raise InvalidParameter(
                f"moves[{k}].target.{program.axes[i].name}",
                move.target[i],
                f"moves the axis by {abs(d):.3g}: a move is 0 or at least {MIN_MOVE:g}",
            )
    moving = moving_axes(program, k)
    if move.coordination == "straight_line" and len(moving) > 1:
        return _straight(program, k, moving, deltas, effective, previous)
    designs: dict[int, AxisMove] = {}
    notes: dict[int, list[str]] = {}
    chosen = effective or {}
    problems = {}
    for i in moving:
        plant, band = plant_of(program, i, k, effective)
        problems[i] = (plant, band, move_problem(program, plant, deltas[i], program.axes[i].limits))
    paced = move.coordination == "synchronized" and move.still_at_stop
    pace_s = 0.0  # synchronized: the longest design so far (the axes with the longest rigid moves first)
    for i in sorted(moving, key=lambda i: -problems[i][2].rigid_floor_s) if paced else moving:
        axis = program.axes[i]
        if previous is not None and i not in chosen and previous.axes[i].own is not None:
            designs[i] = replace(previous.axes[i], command=previous.axes[i].own, stretched_from_s=None)
            pace_s = max(pace_s, _end_s(designs[i]))
            continue
        plant, band, problem = problems[i]
        prior = None if previous is None else previous.axes[i].design
        sufficient = pace_s if paced and pace_s > 0.0 and band is None and i not in chosen else None
        with named(f"moves[{k}].target.{axis.name}"):
            done = _designed(program, problem, band, move.still_at_stop, prior, sufficient)
        own = _absolute(done.command, start[i])
        designs[i] = AxisMove(
            axis.name, own, plant, done.summary, done.solver, band, None, i in chosen, done.design, own
        )
        pace_s = max(pace_s, _end_s(designs[i]))
        notes[i] = [f"{axis.name}: {note}" for note in done.notes]
    warnings = [note for i in moving for note in notes.get(i, [])]
    duration = max((_end_s(a) for a in designs.values()), default=0.0)
    if move.coordination == "synchronized":
        for i, axis_move in designs.items():
            own_s = _end_s(axis_move)
            if own_s < duration * (1.0 - SAME_TIME_RTOL):
                assert axis_move.command is not None
                late, second = None, None
                if len(chosen.get(i, ())) == 4:  # the delayed half designed for a mode of its own
                    omega, zeta = chosen[i][2:]
                    half = move_problem(program, effective_mode(omega, zeta), deltas[i], program.axes[i].limits)
                    prior = None if previous is None else previous.axes[i].second
                    with named(f"moves[{k}].target.{axis_move.axis}"):
                        done = _designed(program, half, None, move.still_at_stop, prior)
                    late, second = _absolute(done.command, start[i]), done.design
                command = stretched(axis_move.command, duration, late)
                designs[i] = replace(axis_move, command=command, stretched_from_s=own_s, second=second)
    axes = tuple(designs.get(i) or _staying(program, i, k) for i in range(len(program.axes)))
    return MoveDesign(k, duration, axes, None, tuple(warnings))


def _end_s(axis_move: AxisMove) -> float:
    return 0.0 if axis_move.command is None else float(axis_move.command.time_s[-1])


def _staying(program: Program, i: int, k: int) -> AxisMove:
    plant, _ = plant_of(program, i, k)
    return AxisMove(program.axes[i].name, None, plant, None, None, None)


def path_limits(program: Program, moving: list[int], direction: list[float]) -> Limits:
    """Each limit of the path parameter: the least over the moving axes of limit_i / |u_i| (None: no axis has it)."""

    def least(name: str) -> float | None:
        values = [
            getattr(program.axes[i].limits, name) / abs(direction[i])
            for i in moving
            if getattr(program.axes[i].limits, name) is not None
        ]
        return min(values) if values else None

    return Limits(least("max_velocity"), least("max_acceleration"), least("max_jerk"))


def path_plant(plants: list[Plant]) -> TransferFunctionPlant:
    """A transfer function whose modes are every plant's (each distinct (w, zeta) once): w_1^2 ... w_n^2 over the
    product of s^2 + 2 zeta w s + w^2, a unit static gain. Only its poles matter: the family cancels them."""
    modes = sorted({(m.natural_frequency_rad_s, m.damping_ratio) for p in plants for m in p.modes()})
    denominator = np.array([1.0])
    gain = 1.0
    for omega, zeta in modes:
        denominator = np.polymul(denominator, [1.0, 2.0 * zeta * omega, omega * omega])
        gain *= omega * omega
    return TransferFunctionPlant(numerator=(gain,), denominator=tuple(float(c) for c in denominator))


def _straight(
    program: Program,
    k: int,
    moving: list[int],
    deltas: list[float],
    effective: Effective | None,
    previous: MoveDesign | None,
) -> MoveDesign:
    move = program.moves[k]
    start = program.stop(k)
    length = math.sqrt(sum(deltas[i] ** 2 for i in moving))
    direction = [d / length for d in deltas]
    limits = path_limits(program, moving, direction)
    plants_bands = {i: plant_of(program, i, k, effective) for i in moving}
    if any(isinstance(p, EffectiveModePlant) for p, _ in plants_bands.values()):  # (no such transfer function)
        raise NoNearbyDesign("a straight line's path plant takes no negative effective damping")
    bands = [b for _, b in plants_bands.values() if b is not None]
    band = (min(b[0] for b in bands), max(b[1] for b in bands)) if bands else None
    plant = path_plant([p for p, _ in plants_bands.values()])
    problem = move_problem(program, plant, length, limits)
    prior = None if previous is None else previous.axes[moving[0]].design
    with named(f"moves[{k}]"):
        done = _designed(program, problem, band, move.still_at_stop, prior)
    names = program.names
    path = PathReport(
        length,
        {names[i]: direction[i] for i in moving},
        limits.max_velocity,
        limits.max_acceleration,
        limits.max_jerk,
        tuple(m.natural_frequency_hz for m in plant.modes()),
    )
    chosen = effective or {}
    axes = []
    for i in range(len(names)):
        if i not in plants_bands:
            axes.append(_staying(program, i, k))
            continue
        own = _absolute(done.command, start[i], direction[i])
        p, b = plants_bands[i]
        axes.append(AxisMove(names[i], own, p, done.summary, done.solver, b, None, i in chosen, done.design, own))
    warnings = tuple(f"path: {note}" for note in done.notes)
    return MoveDesign(k, float(done.command.time_s[-1]), tuple(axes), path, warnings)
