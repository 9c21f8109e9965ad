"""Moves whose plant changes while they run: a design that leaves the true, position-dependent plant still.

An axis whose mode follows a coordinate that moves during the move is a linear time-varying system: no design
for a fixed plant leaves it exactly still (a band design leaves 1e-4 to 1e-3 of the move). Its residual where the
move ends is linear in the command, and the family's command for a fixed mode (w, zeta) depends smoothly on
(w, zeta) while its structure holds: so there is an effective mode, near the modes the move passes through, whose
design leaves the varying plant with no residual (its zeta may be negative: a frequency that falls feeds the
vibration). It is found by Newton's method on the residuals of every such axis at once (the deflection and its
rate over w, by models.varying_mode, relative to the axis's move), the Jacobian by finite differences, a step that
does not lower the residual halved; each evaluation designs the whole move (the path, or every axis and the
synchronization), so limits hold by construction. Where one mode for a stretched axis does not converge, each of
its halves gets a frequency of its own. Bounded in work: at most MAX_ITERATIONS steps of at most HALVINGS
halvings, twice.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from models.commands import PiecewiseCommand
from models.varying_mode import deflection
from optim.programs.cycle import position_function
from optim.programs.moves import Effective, MoveDesign, NoNearbyDesign, design_move, plant_of
from optim.programs.tables import mode_function
from optim.programs.types import Program

Array = NDArray[np.float64]
MAX_ITERATIONS = 8
CONVERGED = 1e-11  # of the axis's move: the residual left (the integration's own error is about 1e-15 of it)
STEP_RELATIVE = 1e-6  # the finite differences' step in w (relative) and in zeta (absolute, times 0.1)
MIN_ZETA, MAX_ZETA = -0.5, 0.9  # an effective damping ratio may be negative (a falling frequency feeds the mode)
HALVINGS = 4  # a Newton step is halved at most this often before the search gives up
MAX_STEP = 0.2  # of a frequency, at most, in one step
MAX_ZETA_STEP = 0.05  # of a damping ratio, at most, in one step


@dataclass(frozen=True)
class VaryingFit:
    """How the effective modes were found: the Newton steps, the designs made, the residual left (of the move)."""

    iterations: int
    designs: int
    residual: float | None  # None: no design near the first could be made (a grid answer)
    converged: bool


def varying_axes(program: Program, k: int) -> list[int]:
    """The axes that move in move k on a table whose coordinate moves too (their plant changes during the move)."""
    out = []
    start, target = program.stop(k), program.moves[k].target
    for i, axis in enumerate(program.axes):
        if axis.table is None or start[i] == target[i] or axis.table.coordinate not in program.names:
            continue
        j = program.axis_index(axis.table.coordinate)
        if start[j] != target[j]:
            out.append(i)
    return out


def residuals(program: Program, k: int, design: MoveDesign, axes: list[int]) -> Array:
    """Each axis's deflection where the move ends and its rate over w there, relative to the axis's move, on the
    true plant (from rest at the stop)."""
    out = []
    start = program.stop(k)
    for i in axes:
        table = program.axes[i].table
        command = design.axes[i].command
        assert table is not None and command is not None
        j = program.axis_index(table.coordinate)
        coordinate = design.axes[j].command
        mode_of_time = _mode_of_time(mode_function(table), coordinate, start[j])
        end = design.duration_s
        solved = deflection(command, mode_of_time, np.array([0.0, end]), np.array([]))
        omega = mode_of_time(end)[0]
        scale = abs(program.moves[k].target[i] - start[i])
        out += [solved.deflection[-1] / scale, solved.rate[-1] / (omega * scale)]
    return np.array(out)


class _Moves:
    """Move k designed for given effective modes of ``axes``, each design from the last one's structure (its
    ``redesign``), with the residuals it leaves on the true plant; counts the designs."""

    def __init__(self, program: Program, k: int, axes: list[int]) -> None:
        self.program, self.k, self.axes = program, k, axes
        # per axis two unknowns: (w, zeta), or for a synchronized axis that is stretched its two halves' w (each
        # half sees the plant at other times: a mode each), their zeta held at ``zetas``' (the plant's at the stop)
        self.split = [False] * len(axes)
        self.zetas = [0.0] * len(axes)
        self.last: MoveDesign | None = None
        self.designs = 0

    def frequency(self, size: int) -> NDArray[np.bool_]:
        """Which unknowns are frequencies (the others damping ratios)."""
        return np.array([c % 2 == 0 or self.split[c // 2] for c in range(size)])

    def effective(self, point: Array) -> Effective:
        out: dict[int, tuple[float, ...]] = {}
        for n, i in enumerate(self.axes):
            a, b = float(point[2 * n]), float(point[2 * n + 1])
            out[i] = (a, self.zetas[n], b, self.zetas[n]) if self.split[n] else (a, b)
        return out

    def __call__(self, point: Array) -> tuple[MoveDesign, Array]:
        self.designs += 1
        design = design_move(self.program, self.k, self.effective(point), self.last)
        return design, residuals(self.program, self.k, design, self.axes)


def _mode_of_time(
    mode: Callable[[float], tuple[float, float]], coordinate: PiecewiseCommand | None, rest: float
) -> Callable[[float], tuple[float, float]]:
    """t -> the mode where the coordinate is at t (its command, or ``rest`` where it stays)."""
    if coordinate is None:
        fixed = mode(rest)
        return lambda _t: fixed
    place = position_function(coordinate)
    return lambda t: mode(place(t))


def design_varying(program: Program, k: int) -> tuple[MoveDesign, VaryingFit | None]:
    """Move k's design, with every varying axis designed for its effective mode (see the module's docstring): one
    mode an axis first, and where a synchronized axis is stretched and that fails, one for each of its halves;
    the band design (with a warning) where neither converges or the family's designs do not follow the mode
    smoothly (a grid answer); unchanged where no axis varies or the load need not be still."""
    axes = varying_axes(program, k)
    if not axes or not program.moves[k].still_at_stop:
        return design_move(program, k), None
    start: list[float] = []
    for i in axes:
        mode = plant_of(program, i, k)[0].modes()[0]  # the plant at the stop: the first guess
        start += [mode.natural_frequency_rad_s, mode.damping_ratio]
    moves = _Moves(program, k, axes)
    moves.zetas = start[1::2]
    worst, stretched, why = math.inf, False, f"within {MAX_ITERATIONS} Newton steps"
    for split in (False, True):
        if split and not stretched:
            break
        moves.split, moves.last = [split] * len(axes), None
        try:
            found, residual, stretched_axes = _search(moves, start)
        except NoNearbyDesign as exc:
            why = f"({exc})"
            break
        stretched = stretched or any(stretched_axes)
        if found is not None:
            return found
        worst = min(worst, residual)
    left = None if math.isinf(worst) else worst
    note = (
        f"the plant changes during the move and no effective mode left it still {why}"
        f"{'' if left is None else f' ({left:.2g} of the move left)'}: the design for the plant at the stop"
        f"{', robust over the band it passes through' if program.family == 'time_optimal' else ''}"
    )
    base = design_move(program, k)
    return replace(base, warnings=(*base.warnings, note)), VaryingFit(MAX_ITERATIONS, moves.designs + 1, left, False)


def _search(moves: _Moves, start: list[float]) -> tuple[tuple[MoveDesign, VaryingFit] | None, float, list[bool]]:
    """Newton from the modes at the stop (``moves.split``: a stretched axis's two halves' frequencies instead of
    its frequency and damping ratio): the design and its fit where it converges, the residual left, and which axes
    were stretched."""
    axes = moves.axes
    point = np.array(start)
    design, r = moves(point)
    stretched = [design.axes[i].stretched_from_s is not None for i in axes]
    moves.split = [s and split for s, split in zip(stretched, moves.split, strict=True)]
    if any(moves.split):
        point = np.array(
            [v for n in range(len(axes)) for v in (start[2 * n], start[2 * n + (0 if moves.split[n] else 1)])]
        )
        design, r = moves(point)
    moves.last = design
    worst = float(np.max(np.abs(r)))
    for iteration in range(MAX_ITERATIONS + 1):
        worst = float(np.max(np.abs(r)))
        if worst <= CONVERGED:
            return (design, VaryingFit(iteration, moves.designs, worst, True)), worst, stretched
        if iteration == MAX_ITERATIONS:
            break
        target = _newton_step(moves, point, r)
        if target is None:
            break
        reach = np.where(moves.frequency(point.size), MAX_STEP * np.abs(point), MAX_ZETA_STEP)
        for _ in range(HALVINGS + 1):  # backtracking: a step that does not lower the residual, or whose design is
            trial = point + np.clip(target - point, -reach, reach)  # not near the last one's, is halved
            try:
                trial_design, trial_r = moves(trial)
            except NoNearbyDesign:
                trial_r = None
            if trial_r is not None and np.max(np.abs(trial_r)) < worst:
                break
            target = 0.5 * (point + target)
        else:
            break
        point, design, r = trial, trial_design, trial_r
        moves.last = design
    return None, worst, stretched


def _newton_step(moves: _Moves, point: Array, r: Array) -> Array | None:
    """The next effective modes: Newton's step, the Jacobian by forward differences (one design per unknown);
    None where it leaves the modes' domain."""
    frequency = moves.frequency(point.size)
    jacobian = np.empty((r.size, point.size))
    for c in range(point.size):
        step = STEP_RELATIVE * point[c] if frequency[c] else 0.1 * STEP_RELATIVE
        moved = point.copy()
        moved[c] += step
        jacobian[:, c] = (moves(moved)[1] - r) / step
    out = point + np.linalg.lstsq(jacobian, -r, rcond=None)[0]
    out[~frequency] = np.clip(out[~frequency], MIN_ZETA, MAX_ZETA)
    if not np.all(np.isfinite(out)) or np.any(out[frequency] <= 0.0):
        return None
    return out


__all__ = ["VaryingFit", "design_varying"]
