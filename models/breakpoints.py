"""Exact commands' breakpoints (Chatlatanagulchai & Pongpanich Sec. 3): merged, snapped, integrated exactly."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from models.commands import MIN_STEP_S, PiecewiseCommand, check_time_grid

# Times closer than this (absolute, or relative to the largest time) are one breakpoint: sums
# such as t_i + t_j and t_j + t_i differ by round-off only, and PiecewiseCommand needs steps of
# at least MIN_STEP_S. Merging moves a kink by at most 2e-9 s.
_MERGE_ABS_S = 2.0 * MIN_STEP_S
_MERGE_REL = 1e-12


def merge_tolerance(times: NDArray[np.float64]) -> float:
    scale = float(np.max(np.abs(times))) if times.size else 0.0
    return max(_MERGE_ABS_S, _MERGE_REL * scale)


def merge_times(times: ArrayLike) -> NDArray[np.float64]:
    """Sorted unique times, those within the merge tolerance of the previous kept one dropped."""
    t = np.sort(np.asarray(times, dtype=float))
    if t.size == 0:
        return t
    keep = np.concatenate(([True], np.diff(t) > merge_tolerance(t)))
    return t[keep]


def snap(times: NDArray[np.floating[Any]], grid: NDArray[np.float64]) -> NDArray[np.intp]:
    """Index of the grid point nearest to each time (every time is within tolerance of one)."""
    idx = np.clip(np.searchsorted(grid, times), 1, max(grid.size - 1, 1))
    if grid.size == 1:
        return np.zeros(times.shape, dtype=int)
    left = grid[idx - 1]
    right = grid[idx]
    return np.where(np.abs(times - left) <= np.abs(right - times), idx - 1, idx)


def integrated(
    time_s: NDArray[np.float64],
    velocity: NDArray[np.float64],
    slope: NDArray[np.float64],
    initial_position: float,
    continuous_orders: int,
) -> PiecewiseCommand:
    """The degree-2 command with these right-hand velocities and slopes; position integrated exactly."""
    h = np.diff(time_s)
    increments = velocity[:-1] * h + 0.5 * slope[:-1] * h * h
    position = initial_position + np.concatenate(([0.0], np.cumsum(increments)))
    return PiecewiseCommand(check_time_grid(time_s), np.array([position, velocity, slope]), continuous_orders)
