"""A measured record (its times, signals and known command): on a uniform grid, and where its free vibration starts."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter

__all__ = ["GAP_RTOL", "JITTER_RTOL", "Record", "free_vibration_start", "uniform_record"]

JITTER_RTOL = 1e-6  # steps within this of their median count as uniform
GAP_RTOL = 0.5  # a step further than this from the median is a gap: refused


@dataclass(frozen=True)
class Record:
    """A measured record: sample times (s), one row per signal, their names, and the command if known."""

    time_s: NDArray[np.float64]
    signals: NDArray[np.float64]  # (signals, samples)
    names: tuple[str, ...]
    command: NDArray[np.float64] | None = None
    command_name: str | None = None


def uniform_record(
    time_s: NDArray[np.float64], signals: NDArray[np.float64]
) -> tuple[float, NDArray[np.float64], bool]:
    """(sample period, signals on the uniform grid t_0 + k dt, whether they were interpolated).

    dt is the median step. Steps within 1e-6 of it are taken as uniform (dt: their mean); a record with jitter up
    to 50 % is linearly interpolated onto the grid (numpy.interp); a larger gap or a step <= 0 is refused."""
    steps = np.diff(time_s)
    if steps.size == 0:
        raise InvalidParameter("time_s", f"{time_s.size} samples", "needs at least 2 samples")
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        k = int(bad[0]) + 1
        raise InvalidParameter(f"time_s[{k}]", float(time_s[k]), "times must increase strictly")
    dt = float(np.median(steps))
    deviation = np.abs(steps / dt - 1.0)
    worst = int(np.argmax(deviation))
    if deviation[worst] > GAP_RTOL:
        raise InvalidParameter(
            f"time_s[{worst + 1}]",
            float(time_s[worst + 1]),
            f"a step of {steps[worst]:.6g} s against the median {dt:.6g} s: the record has a gap "
            f"(steps must stay within {100 * GAP_RTOL:g} % of the median)",
        )
    if deviation[worst] <= JITTER_RTOL:  # uniform: the mean step, free of the median's rounding
        return float(time_s[-1] - time_s[0]) / steps.size, signals, False
    n = math.floor((time_s[-1] - time_s[0]) / dt + 1e-9) + 1
    grid = time_s[0] + dt * np.arange(n)
    resampled = np.vstack([np.interp(grid, time_s, row) for row in signals])
    return dt, resampled, True


def free_vibration_start(
    record: Record, dt: float, signals: NDArray[np.float64], start_s: float | None
) -> tuple[int, str]:
    """Index where the free vibration starts, and why: the first sample at or after ``start_s``; else
    where the known command last changes; else the record's largest excursion (the sum over the signals
    of the squared deviation from their medians, each over its own variance)."""
    n = signals.shape[1]
    if start_s is not None:
        k = math.ceil((start_s - float(record.time_s[0])) / dt - 1e-9)
        if not 0 <= k < n:
            raise InvalidParameter("start_s", start_s, "must lie within the record's times")
        return k, "start_s"
    if record.command is not None:
        command = record.command
        if command.size != n:  # resampled: the command on the same grid
            grid = float(record.time_s[0]) + dt * np.arange(n)
            command = np.interp(grid, record.time_s, record.command)
        span = float(np.max(command) - np.min(command))
        moving = np.flatnonzero(np.abs(np.diff(command)) > 1e-9 * max(span, 1e-300))
        if span == 0.0 or moving.size == 0:
            return 0, "command_end"  # a command that never moves: the whole record is free
        return int(moving[-1]) + 1, "command_end"
    centred = signals - np.median(signals, axis=1, keepdims=True)
    var = np.var(centred, axis=1, keepdims=True)
    energy = np.sum(centred**2 / np.where(var > 0, var, 1.0), axis=0)
    return int(np.argmax(energy)), "largest_excursion"
