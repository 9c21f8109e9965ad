"""Arcs: a command whose held derivative (acceleration or jerk) is constant on consecutive intervals.

The exact command (a breakpoint at every switch), the constraint functions of the refinement (end
state, residual moments, node bounds, band points) and the grid solution's arcs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.commands import PiecewiseCommand
from optim.families.time_optimal.types import Arc

Array = NDArray[np.float64]
SNAP = 1e-5  # a step within this of +-1 or 0 (of the unit) is on that level


def command_of(
    arcs: tuple[Arc, ...], order: int, rest_to_rest: bool, initial: tuple[float, ...] = ()
) -> PiecewiseCommand:
    """The exact command: the held derivative on each arc, integrated in closed form from rest or from the
    motion ``initial`` = (0, velocity[, acceleration]) (Spec.start_state); at rest (or cruising at the final
    speed) after the last arc."""
    starts = np.array([a.start_s for a in arcs])
    time_s = np.append(starts, starts[-1] + arcs[-1].duration_s)
    command = PiecewiseCommand.from_held_steps(time_s, [*(a.level for a in arcs), 0.0], order, initial)
    if not rest_to_rest and order == 3:
        command.derivatives[2, -1] = 0.0  # the acceleration ends at 0 (to round-off)
    return command


@dataclass(frozen=True)
class ArcPeaks:
    """command_of's peaks over the command and its end position, in closed form (``exact_peaks``)."""

    velocity: float
    acceleration: float
    jerk: float | None  # None with a held acceleration (the jerk is impulsive)
    end_position: float


def exact_peaks(arcs: tuple[Arc, ...], order: int, initial: tuple[float, ...] = ()) -> ArcPeaks:
    """max |velocity|, |acceleration| and |jerk| of ``command_of(arcs, order, _, initial)`` and its end position,
    integrated per arc in closed form (as PiecewiseCommand.from_held_steps, from the arcs' start times): the
    velocity's extremum inside an arc of a held jerk is where the acceleration crosses 0, at tau = -a / j. What
    PiecewiseCommand.peak_abs gives (to round-off: tests/optim/test_time_optimal_arcs.py), 5-10 times faster on
    the refinement's commands (a few arcs: the per-call cost of its general form dominated)."""
    starts = np.array([a.start_s for a in arcs])
    h = np.diff(np.append(starts, starts[-1] + arcs[-1].duration_s))
    held = np.array([a.level for a in arcs])
    v0 = initial[1] if len(initial) > 1 else 0.0
    a0 = initial[2] if len(initial) > 2 and order == 3 else 0.0
    if order == 2:
        v_end = np.cumsum(held * h) + v0
        v_start = np.concatenate(([v0], v_end[:-1]))
        position = float(np.sum(v_start * h + held * h**2 / 2))
        velocity = max(abs(v0), float(np.max(np.abs(v_end))))
        return ArcPeaks(velocity, float(np.max(np.abs(held))), None, position)
    a_end = np.cumsum(held * h) + a0
    a_start = np.concatenate(([a0], a_end[:-1]))
    v_end = np.cumsum(a_start * h + held * h**2 / 2) + v0
    v_start = np.concatenate(([v0], v_end[:-1]))
    position = float(np.sum(v_start * h + a_start * h**2 / 2 + held * h**3 / 6))
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = -a_start / held  # where the acceleration crosses 0 inside the arc: the velocity's extremum
    inside = (held != 0.0) & (tau > 0.0) & (tau < h)
    turning = v_start[inside] + a_start[inside] * tau[inside] / 2  # v + a tau + j tau^2 / 2 with j tau = -a
    velocity = max(abs(v0), float(np.max(np.abs(v_end))), float(np.max(np.abs(turning), initial=0.0)))
    acceleration = max(abs(a0), float(np.max(np.abs(a_end))))
    return ArcPeaks(velocity, acceleration, float(np.max(np.abs(held))), position)


def same_command(a: tuple[Arc, ...], b: tuple[Arc, ...], rtol: float) -> bool:
    """The same levels, and durations equal to ``rtol`` of the whole."""
    if len(a) != len(b) or any(x.level != y.level for x, y in zip(a, b, strict=True)):
        return False
    total = sum(x.duration_s for x in a)
    return all(abs(x.duration_s - y.duration_s) <= rtol * total for x, y in zip(a, b, strict=True))


def merged(arcs: tuple[Arc, ...]) -> tuple[Arc, ...]:
    """Consecutive arcs on the same level joined, empty arcs dropped."""
    out: list[Arc] = []
    for arc in arcs:
        if arc.duration_s <= 0.0:
            continue
        if out and out[-1].level == arc.level:
            last = out[-1]
            out[-1] = Arc(last.start_s, arc.start_s + arc.duration_s - last.start_s, last.level)
        else:
            out.append(arc)
    return tuple(out)


def arcs_of(levels: Array, dt: float) -> tuple[Arc, ...]:
    """The grid solution as arcs: runs of equal values merged (found at once, not step by step)."""
    if not levels.size:
        return ()
    firsts = [0, *(np.flatnonzero(levels[1:] != levels[:-1]) + 1).tolist()]
    ends = [*firsts[1:], levels.size]
    return tuple(Arc(k * dt, (end - k) * dt, float(levels[k])) for k, end in zip(firsts, ends, strict=True))


def structure(values: Array, dt: float) -> tuple[list[float], list[float], list[bool]]:
    """Initial durations, levels (in the unit) and which levels are free, from a grid solution x: runs of
    a saturated or zero level become arcs on that level; a single fractional step between two different
    such levels is a switch inside the step (split in proportion); other fractional runs are arcs of a
    free level."""
    snapped = np.where(np.abs(values - 1) < SNAP, 1.0, np.where(np.abs(values + 1) < SNAP, -1.0, values))
    snapped = np.where(np.abs(snapped) < SNAP, 0.0, snapped)
    fixed = np.isin(snapped, (-1.0, 0.0, 1.0))
    runs: list[tuple[int, int, bool]] = []
    k = 0
    while k < values.size:
        j = k
        while j + 1 < values.size and fixed[j + 1] == fixed[k] and (not fixed[k] or snapped[j + 1] == snapped[k]):
            j += 1
        runs.append((k, j + 1, bool(fixed[k])))
        k = j + 1
    durations: list[float] = []
    levels: list[float] = []
    free: list[bool] = []
    for i, (a, b, is_fixed) in enumerate(runs):
        if is_fixed:
            durations.append((b - a) * dt)
            levels.append(float(snapped[a]))
            free.append(False)
            continue
        left = runs[i - 1] if i > 0 else None
        right = runs[i + 1] if i + 1 < len(runs) else None
        if b - a == 1 and left and right and left[2] and right[2] and snapped[left[0]] != snapped[right[0]]:
            l1, l2 = snapped[left[0]], snapped[right[0]]
            alpha = float(np.clip((values[a] - l2) / (l1 - l2), 0.0, 1.0))
            durations[-1] += alpha * dt
            durations.append(-(1 - alpha) * dt)  # marker: added to the next run below
            levels.append(math.nan)
            free.append(False)
            continue
        durations.append((b - a) * dt)
        levels.append(float(np.mean(values[a:b])))
        free.append(True)
    out_d: list[float] = []
    out_l: list[float] = []
    out_f: list[bool] = []
    carry = 0.0
    for d, lv, f in zip(durations, levels, free, strict=True):
        if math.isnan(lv):
            carry = -d
            continue
        out_d.append(d + carry)
        out_l.append(lv)
        out_f.append(f)
        carry = 0.0
    return out_d, out_l, out_f
