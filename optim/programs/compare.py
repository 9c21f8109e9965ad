"""The recipes a program is compared with, each run through the same cycle and checks (optim.programs.cycle):

- ``ruckig_zv`` / ``ruckig_zvd``: Ruckig's time-synchronized rigid optimum of every move (all axes, their limits),
  each axis convolved with ZV (ZVD) at its modes as they are at the move's stop (the true frequency there);
- ``klipper_mzv`` / ``klipper_ei``: the same rigid moves through Klipper's per-axis shaper (kin_shaper.c's
  impulses, its default damping ratio 0.1) at one frequency per axis, as firmware is set: the axis's mode in the
  middle of its plant table's range (or its plant's).

A move whose load need not be still is the rigid move, unshaped, in every recipe (as in the program). Each row
gives the cycle time, its ratio to the program's, and the largest residual any stop is left with (of its move).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from models.commands import PiecewiseCommand
from models.errors import DomainError
from models.plants import Plant
from models.rigid_motion import synchronized_moves
from models.shapers import ImpulseSequence, convolve, shape_command, zv_family
from optim.families.input_shaped.firmware import klipper_impulses
from optim.programs.cycle import cycle
from optim.programs.moves import AxisMove, MoveDesign, plant_of
from optim.programs.tables import plant_at
from optim.programs.types import Program
from optim.results import Block

KLIPPER_DAMPING_RATIO = 0.1  # Klipper's default damping_ratio_x / _y (configuration reference, [input_shaper])
Shaper = Callable[[int, int], ImpulseSequence]  # (move, axis) -> the axis's shaper in that move


@dataclass(frozen=True)
class RecipeRow(Block):
    method: str
    cycle_time_s: float | None  # None: the recipe has no answer (``reason``)
    cycle_time_ratio: float | None  # this recipe's cycle time over the program's
    max_stop_residual_fraction: float | None  # the largest residual any still stop is left with, of its move
    description: str
    reason: str | None = None


def _per_mode(plant: Plant, derivatives: int) -> ImpulseSequence:
    shaper = ImpulseSequence(np.array([1.0]), np.array([0.0]))
    for mode in plant.modes():
        shaper = convolve(shaper, zv_family(mode, derivatives))
    return shaper


def true_zv(program: Program, derivatives: int) -> Shaper:
    """ZV (derivatives 0) or ZVD (1) at every mode of the axis's plant at the move's stop."""
    return lambda k, i: _per_mode(plant_of(program, i, k)[0], derivatives)


def firmware(program: Program, kind: str) -> Shaper:
    """Klipper's ``kind`` at one frequency per axis: its mode in the middle of its table (or its plant's)."""
    frequencies = []
    for axis in program.axes:
        plant = axis.plant if axis.table is None else plant_at(axis.table, 0.5 * (axis.table.low + axis.table.high))
        frequencies.append(plant.modes()[0].natural_frequency_hz if plant.modes() else None)

    def shaper(k: int, i: int) -> ImpulseSequence:
        f = frequencies[i]
        return (
            ImpulseSequence(np.array([1.0]), np.array([0.0]))
            if f is None
            else klipper_impulses(kind, f, KLIPPER_DAMPING_RATIO)
        )

    return shaper


def recipe_moves(program: Program, shaper: Shaper) -> list[MoveDesign]:
    """Every move as Ruckig's synchronized rigid optimum, each axis shaped (unshaped where the load need not be
    still)."""
    out = []
    for k, move in enumerate(program.moves):
        start = program.stop(k)
        deltas = [b - a for a, b in zip(start, move.target, strict=True)]
        limits = [a.limits for a in program.axes]
        rigid = synchronized_moves(
            deltas,
            [lim.max_velocity for lim in limits],
            [lim.max_acceleration for lim in limits],
            [lim.max_jerk for lim in limits],
        )
        axes = []
        for i, r in enumerate(rigid):
            plant = plant_of(program, i, k)[0]
            if r is None:
                axes.append(AxisMove(program.axes[i].name, None, plant, None, None, None))
                continue
            command = PiecewiseCommand.from_held_steps(r.edges_s, [*r.levels, 0.0], r.order, (start[i],))
            if move.still_at_stop:
                command = shape_command(command, shaper(k, i))
            axes.append(AxisMove(program.axes[i].name, command, plant, None, None, None))
        duration = max((float(a.command.time_s[-1]) for a in axes if a.command is not None), default=0.0)
        out.append(MoveDesign(k, duration, tuple(axes), None, ()))
    return out


RECIPES: dict[str, tuple[Callable[[Program], Shaper], str]] = {
    "ruckig_zv": (lambda p: true_zv(p, 0), "Ruckig's synchronized rigid optimum, ZV per axis at the stop's modes"),
    "ruckig_zvd": (lambda p: true_zv(p, 1), "Ruckig's synchronized rigid optimum, ZVD per axis at the stop's modes"),
    "klipper_mzv": (
        lambda p: firmware(p, "mzv"),
        "Ruckig's rigid optimum through Klipper's mzv, one frequency an axis",
    ),
    "klipper_ei": (lambda p: firmware(p, "ei"), "Ruckig's rigid optimum through Klipper's ei, one frequency an axis"),
}


def compare(program: Program, cycle_time_s: float) -> tuple[RecipeRow, ...]:
    """One row per recipe (RECIPES), run through the program's own cycle and checks."""
    rows = []
    for name, (make, description) in RECIPES.items():
        try:
            designs = recipe_moves(program, make(program))
            starts, axes = cycle(program, designs, samples=False)
        except (ValueError, DomainError) as exc:  # Ruckig refuses the limits; the true plant's simulation is too long
            rows.append(RecipeRow(name, None, None, None, description, str(exc)))
            continue
        worst = 0.0
        for k, move in enumerate(program.moves):
            for i, axis in enumerate(axes):
                delta = abs(move.target[i] - program.stop(k)[i])
                if delta and move.still_at_stop:
                    worst = max(worst, float(axis.stop_residuals[k]) / delta)
        total = float(starts[-1])
        rows.append(RecipeRow(name, total, total / cycle_time_s, worst, description))
    return tuple(rows)
