"""A measured record (its times, signals and known command): on a uniform grid, and where its free vibration starts."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter

__all__ = ["GAP_RTOL", "JITTER_RTOL", "Record", "free_vibration_start", "printed_quantum_s", "uniform_record"]

JITTER_RTOL = 1e-6  # steps within this of their median count as uniform
GAP_RTOL = 0.5  # a step further than this from the median is a gap: refused
MAX_DECIMALS = 9  # the finest printed time resolution looked for (1 ns)
QUANTUM_TOLERANCE = 1e-3  # of the quantum: times within this of its multiples were printed at it (float round-off)
ROUNDING_QUANTA = 2.0  # a rounded uniform record's times lie within this many quanta of their least-squares line
ROUNDING_SHARE = 0.05  # ... where that is less than this share of the step (else its rounding tells nothing)


@dataclass(frozen=True)
class Record:
    """A measured record: sample times (s), one row per signal, their names, and the command if known."""

    time_s: NDArray[np.float64]
    signals: NDArray[np.float64]  # (signals, samples)
    names: tuple[str, ...]
    command: NDArray[np.float64] | None = None
    command_name: str | None = None


def printed_quantum_s(time_s: NDArray[np.float64]) -> float | None:
    """The resolution the times were printed at (10^-d s, d <= MAX_DECIMALS, the coarsest that every time is a
    multiple of), or None: ``%.6f`` timestamps (Klipper's accelerometer dumps) give 1e-6."""
    for decimals in range(MAX_DECIMALS + 1):
        scaled = time_s * 10.0**decimals
        if float(np.max(np.abs(scaled - np.round(scaled)))) <= QUANTUM_TOLERANCE:
            return 10.0**-decimals
    return None


def _fitted_grid(time_s: NDArray[np.float64]) -> tuple[float, float, float]:
    """The least-squares line t_k = t_0 + k dt through the times: (t_0, dt, the largest deviation from it)."""
    k = np.arange(time_s.size, dtype=float)
    k_mean, t_mean = float(np.mean(k)), float(np.mean(time_s))
    dt = float(np.dot(k - k_mean, time_s - t_mean) / np.dot(k - k_mean, k - k_mean))
    start = t_mean - dt * k_mean
    return start, dt, float(np.max(np.abs(time_s - (start + dt * k))))


def uniform_record(
    time_s: NDArray[np.float64], signals: NDArray[np.float64]
) -> tuple[float, NDArray[np.float64], bool]:
    """(sample period, signals on the uniform grid t_0 + k dt, whether they were interpolated).

    A record sampled uniformly whose times were printed rounded is uniform: dt is the slope of the least-squares
    line t_0 + k dt through them, which every time lies within ROUNDING_QUANTA printed quanta of (the rounding
    is half a quantum; the fitted line is off the true grid by up to 0.19 us at a 3200 Hz record's %.6f ends) (a 3200 Hz
    accelerometer's ``%.6f`` times have steps of 312 and 313 us; their median would read 3205 Hz). Otherwise dt
    is the median step; a record with jitter up to 50 % is linearly interpolated onto the grid (numpy.interp);
    a larger gap or a step <= 0 is refused."""
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
    _, slope, off_line = _fitted_grid(time_s)
    quantum = printed_quantum_s(time_s)
    rounding = 0.0 if quantum is None else ROUNDING_QUANTA * quantum
    if off_line <= JITTER_RTOL * slope or off_line <= rounding <= ROUNDING_SHARE * slope:
        return slope, signals, False  # uniform samples whose times were printed rounded
    n = math.floor((time_s[-1] - time_s[0]) / dt + 1e-9) + 1
    grid = time_s[0] + dt * np.arange(n)
    resampled = np.vstack([np.interp(grid, time_s, row) for row in signals])
    return dt, resampled, True


EXCURSION_SAMPLES = 9  # the span of the largest excursion's energy


def free_vibration_start(
    record: Record, dt: float, signals: NDArray[np.float64], start_s: float | None
) -> tuple[int, str]:
    """Index where the free vibration starts, and why: the first sample at or after ``start_s``; else
    where the known command last changes; else the record's largest excursion (the sum over the signals
    of the squared deviation from their medians, each over its own variance, summed over EXCURSION_SAMPLES around
    each sample; its largest sample there)."""
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
    # the largest excursion of the energy over EXCURSION_SAMPLES around each sample (a vibration lasts, a noise spike
    # does not: at 25 % noise a lone spike outweighed a knock's peak), then its largest sample there
    width = min(EXCURSION_SAMPLES, n)
    smooth = np.convolve(energy, np.ones(width), mode="same")
    centre = int(np.argmax(smooth))
    low = max(0, centre - width // 2)
    return low + int(np.argmax(energy[low : low + width])), "largest_excursion"
