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
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.signal import fftconvolve

from models.errors import InvalidParameter

__all__ = [
    "MAX_HALF_PERIODS",
    "MAX_TEST_SAMPLES",
    "ResonanceTest",
    "check_test",
    "command_samples",
    "command_switches",
    "overlay_amplitude",
    "start_in_record",
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
    start_s: float = 0.0  # where the test starts in its record (Klipper's dwell before it)

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


def command_switches(
    test: ResonanceTest, rate_hz: float, samples: int = 0
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """The test's command in a record as (switch times from the record's start (the first is 0), the level from each,
    the samples simulated): the vibration's quarter periods and the overlay's flips merged, at rest before the test
    (which starts at ``test.start_s``) and after it; ``samples`` the record's (0: to the test's end)."""
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
    level = np.concatenate([vibration + _sweeping(test, middle), [0.0]])  # at rest from the end
    times = np.concatenate([times, [ends[-1]]]) + test.start_s
    before = np.searchsorted(times, 0.0, side="right") - 1  # the switch in force at the record's start
    if before < 0:
        times, level = np.concatenate([[0.0], times]), np.concatenate([[0.0], level])
    else:
        times, level = np.concatenate([[0.0], times[before + 1 :]]), level[before:]
    count = samples if samples > 0 else int((ends[-1] + test.start_s) * rate_hz)
    return times, np.asarray(level, float), max(count, 1)


def overlay_amplitude(signals: NDArray[np.float64], rate_hz: float, test: ResonanceTest) -> tuple[float, float]:
    """(the sweeping overlay's amplitude in the record, mm/s^2, its standard error): each signal's least-squares
    projection on the overlay's +-1 pattern during the test (at rest the toolhead's acceleration follows the command:
    the modes pass the slow square wave at unit gain), their root sum of squares (the accelerometer's axes see the
    motion's projections), the error from each residual's variance over the samples. Klipper before the sweeping test,
    or SWEEPING_PERIOD=0, leaves no overlay: an amplitude within a few standard errors of 0."""
    if test.sweeping_period_s <= 0.0:
        return 0.0, 0.0
    pattern_test = replace(test, sweeping_accel_mm_s2=1.0, start_s=0.0)
    times = np.arange(np.atleast_2d(signals).shape[1]) / rate_hz - test.start_s
    inside = (times >= 0.0) & (times < test.duration_s)
    pattern = np.where(inside, _sweeping(pattern_test, np.maximum(times, 0.0)), 0.0)
    centred = np.atleast_2d(signals) - np.mean(np.atleast_2d(signals), axis=1, keepdims=True)
    norm = float(pattern @ pattern)
    if norm == 0.0:
        return 0.0, 0.0
    amplitudes = centred @ pattern / norm
    residual = centred - np.outer(amplitudes, pattern)
    errors = np.sqrt(np.var(residual, axis=1) / norm)
    amplitude = float(np.sqrt(np.sum(amplitudes**2)))
    return amplitude, float(np.sqrt(np.sum((amplitudes * errors) ** 2)) / max(amplitude, 1e-300))


def start_in_record(signals: NDArray[np.float64], rate_hz: float, test: ResonanceTest) -> float:
    """Where the test starts in its record, s: the lag that best aligns the record with the test's sampled command
    (the largest sum over the signals of their squared cross-correlations, refined by a parabola; a chirp's
    correlation is one sharp peak). The modes delay the response near their resonances, by a few milliseconds at
    Klipper's rates: the ridge's line (excitation.sweep_band) is 30 times coarser."""
    command = command_samples(replace(test, start_s=0.0), rate_hz)
    centred = np.atleast_2d(signals) - np.mean(np.atleast_2d(signals), axis=1, keepdims=True)
    score = np.sum([fftconvolve(row, command[::-1], mode="full") ** 2 for row in centred], axis=0)
    k = int(np.clip(np.argmax(score), 1, score.size - 2))
    before, at, after = score[k - 1], score[k], score[k + 1]
    curvature = before - 2.0 * at + after
    shift = 0.5 * (before - after) / curvature if curvature < 0.0 else 0.0
    return float((k + shift - (command.size - 1)) / rate_hz)
