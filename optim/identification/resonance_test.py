"""The commanded acceleration of Klipper's resonance test (TEST_RESONANCES, SHAPER_CALIBRATE), the excitation a sweep's
record and a Klipper resonance CSV respond to (klippy/extras/resonance_tester.py at Klipper3d/klipper 84104bbbd).

- VibrationPulseTestGenerator.gen_test: from f = min_freq while f <= max_freq + 1e-6, a quarter period 1/(4 f) at
  +s accel_per_hz f, one at -s accel_per_hz f, then f += hz_per_sec / (2 f) and s = -s (f rises hz_per_sec per
  second).
- SweepingVibrationsTestGenerator.gen_test adds +-sweeping_accel (a slow back-and-forth of the toolhead) whose sign
  flips sweeping_period sqrt(2)/8 into the test, then (sqrt(2)/8 + 1/4) periods later, then every half period; a
  sweeping_period of 0 leaves it out.

The command is piecewise constant in time: ``command_switches`` gives its switches (for an exact simulation between
samples), ``command_samples`` its level at each sample's time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter

__all__ = [
    "MAX_HALF_PERIODS",
    "MAX_TEST_SAMPLES",
    "ResonanceTest",
    "check_test",
    "command_samples",
    "command_switches",
    "vibration_levels",
]

MAX_TEST_SAMPLES = 4_000_000  # samples of a simulated test (units of work: 1250 s at 3200 Hz)
MAX_HALF_PERIODS = 400_000  # the vibration's half periods (gen_test's steps): Klipper's default test has 18,200


@dataclass(frozen=True)
class ResonanceTest:
    """The test's settings ([resonance_tester] and TEST_RESONANCES' parameters), Klipper's defaults for x and y."""

    min_freq_hz: float = 5.0  # min_freq / FREQ_START
    max_freq_hz: float = 135.0  # max_freq / FREQ_END
    hz_per_sec: float = 1.0  # hz_per_sec / HZ_PER_SEC
    accel_per_hz: float = 60.0  # accel_per_hz / ACCEL_PER_HZ (mm/s^2 per Hz)
    sweeping_accel_mm_s2: float = 400.0  # sweeping_accel / SWEEPING_ACCEL
    sweeping_period_s: float = 1.2  # sweeping_period / SWEEPING_PERIOD (0: none)

    @property
    def duration_s(self) -> float:
        """The test's length: the frequency rises hz_per_sec per second from min to max."""
        return (self.max_freq_hz - self.min_freq_hz) / self.hz_per_sec


def vibration_levels(test: ResonanceTest) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(the end times of the vibration's quarter periods, their accelerations) by gen_test's recursion (see the
    module). The recursion runs once per half period: its count is bounded by the caller's MAX_TEST_SAMPLES."""
    ends: list[float] = []
    levels: list[float] = []
    f, sign, t = test.min_freq_hz, 1.0, 0.0
    while f <= test.max_freq_hz + 1e-6:
        quarter = 0.25 / f
        accel = test.accel_per_hz * f
        ends += [t + quarter, t + 2 * quarter]
        levels += [sign * accel, -sign * accel]
        t += 2 * quarter
        f += 2.0 * quarter * test.hz_per_sec
        sign = -sign
    return np.asarray(ends), np.asarray(levels)


def _sweeping(test: ResonanceTest, time_s: NDArray[np.float64]) -> NDArray[np.float64]:
    """The sweeping overlay at each time: +sweeping_accel until its first flip, its sign flipping at each flip."""
    if test.sweeping_period_s <= 0.0:
        return np.zeros_like(time_s)
    first = test.sweeping_period_s * math.sqrt(2.0) / 8.0
    second = first + test.sweeping_period_s * (math.sqrt(2.0) / 8.0 + 0.25)
    half = test.sweeping_period_s / 2.0
    flips = np.where(time_s < first, 0, np.where(time_s < second, 1, 2 + np.floor((time_s - second) / half)))
    sign: NDArray[np.float64] = np.where(flips % 2 == 0, 1.0, -1.0) * test.sweeping_accel_mm_s2
    return sign


def check_test(test: ResonanceTest, rate_hz: float) -> None:
    """An InvalidParameter naming sweep_hz_per_sec where simulating the test at ``rate_hz`` is more work than the
    caps allow."""
    samples = int(test.duration_s * rate_hz)
    half_periods = (test.min_freq_hz + test.max_freq_hz) * test.duration_s  # 2 x the integral of f over the test
    if samples > MAX_TEST_SAMPLES or half_periods > MAX_HALF_PERIODS:
        raise InvalidParameter(
            "sweep_hz_per_sec",
            test.hz_per_sec,
            f"a test of {test.duration_s:.4g} s at {rate_hz:.6g} Hz is {samples} samples and {half_periods:.0f} half "
            f"periods: at most {MAX_TEST_SAMPLES} and {MAX_HALF_PERIODS} are simulated (sweep faster, or a narrower "
            "band)",
        )


def command_samples(test: ResonanceTest, rate_hz: float) -> NDArray[np.float64]:
    """The test's commanded acceleration (mm/s^2) sampled at ``rate_hz`` from its start (see the module)."""
    check_test(test, rate_hz)
    ends, levels = vibration_levels(test)
    time_s = np.arange(int(ends[-1] * rate_hz)) / rate_hz
    vibration = levels[np.minimum(np.searchsorted(ends, time_s, side="right"), levels.size - 1)]
    command: NDArray[np.float64] = vibration + _sweeping(test, time_s)
    return command


def command_switches(test: ResonanceTest, rate_hz: float) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """The test's command as (switch times from 0 (the first is 0), the level from each, the samples at ``rate_hz``
    the test lasts): the vibration's quarter periods and the overlay's flips merged."""
    check_test(test, rate_hz)
    ends, levels = vibration_levels(test)
    flips = np.empty(0)
    if test.sweeping_period_s > 0.0:
        first = test.sweeping_period_s * math.sqrt(2.0) / 8.0
        second = first + test.sweeping_period_s * (math.sqrt(2.0) / 8.0 + 0.25)
        flips = np.concatenate([[first], np.arange(second, ends[-1], test.sweeping_period_s / 2.0)])
    times = np.union1d(np.concatenate([[0.0], ends[:-1]]), flips[flips < ends[-1]])
    middle = np.concatenate([(times[:-1] + times[1:]) / 2.0, [(times[-1] + ends[-1]) / 2.0]])  # off every switch
    vibration = levels[np.minimum(np.searchsorted(ends, middle, side="right"), levels.size - 1)]
    level: NDArray[np.float64] = vibration + _sweeping(test, middle)
    return times, level, int(ends[-1] * rate_hz)
