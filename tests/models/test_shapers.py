"""Impulse sequences, V(omega, zeta) and shaped commands (models.shapers); the drive's in test_drives.py.

Expected values come from independent routes: exact simulation of a mode plant
(tests.shaper_oracle.v_by_simulation), closed-form integrals written out here and the undamped
closed forms of V.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.metrics import metrics
from models.plants import TransferFunctionPlant
from models.shapers import (
    ImpulseSequence,
    RampTrain,
    convolve,
    percentage_vibration,
    shape_command,
    shape_samples,
    vibration_band,
)
from models.simulation import simulate
from tests.shaper_oracle import v_by_simulation

RNG = np.random.default_rng(11)


def zv_by_hand(omega: float, zeta: float) -> ImpulseSequence:
    """ZV written out (Singer & Seering): A = (1, K)/(1 + K), t = (0, pi/omega_d)."""
    k = math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    return ImpulseSequence(np.array([1.0, k]) / (1 + k), np.array([0.0, math.pi / (omega * math.sqrt(1 - zeta**2))]))


@pytest.mark.parametrize("zeta", [0.0, 0.03, 0.2])
def test_percentage_vibration_equals_simulated_residual(zeta):
    # Random sequences at random frequencies: the formula of Sec. 3.1 against two exact
    # simulations (shared nothing but the plant); both are exact, so 1e-9 is round-off room.
    for _ in range(5):
        count = int(RNG.integers(2, 6))
        amplitudes = RNG.uniform(0.1, 1.0, count)
        amplitudes /= amplitudes.sum()
        times = np.concatenate([[0.0], np.cumsum(RNG.uniform(0.05, 0.4, count - 1))])
        omega = float(RNG.uniform(5.0, 40.0))
        expected = v_by_simulation(amplitudes, times, omega, zeta)
        got = float(percentage_vibration(ImpulseSequence(amplitudes, times), omega, zeta))
        assert got == pytest.approx(expected, rel=1e-9, abs=1e-12)


def test_percentage_vibration_is_vectorised_and_matches_the_undamped_closed_form():
    # Undamped ZV: V(r) = |cos(pi r / 2)| (the two unit phasors half a period apart).
    shaper = zv_by_hand(3.0, 0.0)
    ratios = np.linspace(0.1, 3.0, 50)
    expected = np.abs(np.cos(np.pi * ratios / 2))
    np.testing.assert_allclose(percentage_vibration(shaper, 3.0 * ratios, 0.0), expected, atol=1e-14)
    grid = percentage_vibration(shaper, 3.0 * ratios[None, :], np.array([[0.0], [0.1]]))
    assert grid.shape == (2, 50)


def test_convolution_cancels_both_modes_of_a_two_mode_plant():
    # Modes at 5 Hz (zeta 0.02) and 23 Hz (zeta 0.03) of the shared two-mode example.
    plant = TransferFunctionPlant((20611800.0,), (1.0, 9.92743, 21881.9, 34801.4, 20611800.0))
    low, high = plant.modes()
    first = zv_by_hand(low.natural_frequency_rad_s, low.damping_ratio)
    second = zv_by_hand(high.natural_frequency_rad_s, high.damping_ratio)
    both = convolve(first, second)
    assert both.count == 4 and both.gain == pytest.approx(1.0, abs=1e-15)

    def residuals(shaper: ImpulseSequence) -> list[float]:
        command = RampTrain.single(0.0, 0.0, 1.0).shaped(shaper).to_command()
        modes = sorted(metrics(simulate(plant, command)).modes, key=lambda m: m.natural_frequency_hz)
        return [m.residual_velocity_amplitude for m in modes]

    # Exact shapers on an exact simulation: the cancelled modes are at round-off (1e-12 of the
    # unshaped ~1), while a shaper for one mode leaves the other clearly excited (> 1e-3).
    assert max(residuals(both)) < 1e-12
    assert residuals(first)[0] < 1e-12 < 1e-3 < residuals(first)[1]
    assert residuals(second)[1] < 1e-12 < 1e-3 < residuals(second)[0]


def test_merged_adds_coincident_impulses():
    merged = ImpulseSequence.merged(np.array([0.25, 0.25, 0.5]), np.array([0.0, 0.1, 0.1 + 1e-15]))
    np.testing.assert_allclose(merged.amplitudes, [0.25, 0.75])
    np.testing.assert_allclose(merged.times_s, [0.0, 0.1])


@pytest.mark.parametrize(
    ("amplitudes", "times", "field"),
    [
        ([1.0], [0.5], "impulses.times_s[0]"),
        ([0.5, 0.5], [0.0, 0.0], "impulses.times_s"),
        ([1.0, np.nan], [0.0, 1.0], "impulses"),
    ],
)
def test_invalid_sequences_name_the_field(amplitudes, times, field):
    with pytest.raises(InvalidParameter) as info:
        ImpulseSequence(np.array(amplitudes), np.array(times))
    assert info.value.field == field


def ramp_integral(t: np.ndarray, start: float, rise: float, height: float) -> np.ndarray:
    """Closed-form integral of one ramp-step: h tau^2/(2d) while rising, h (tau - d/2) after."""
    tau = np.clip(t - start, 0.0, None)
    if rise == 0.0:
        return height * tau
    return height * np.where(tau < rise, tau**2 / (2 * rise), tau - rise / 2)


def test_ramp_train_command_is_exact_between_and_at_its_kinks():
    train = RampTrain(np.array([0.0, 0.7, 0.7, 2.0]), np.array([1.0, 0.0, 0.5, 0.3]), np.array([1.0, 0.4, -0.3, 0.2]))
    command = train.to_command(initial_position=2.0)
    t = np.linspace(-0.5, 4.0, 2001)
    # Velocity: the train's own formula; position: the closed-form integrals written above.
    np.testing.assert_allclose(command.evaluate(1, t), train.velocity(t), atol=1e-14)
    ramps = zip(train.start_s, train.rise_s, train.height, strict=True)
    position = 2.0 + sum(ramp_integral(t, s, d, h) for s, d, h in ramps)
    np.testing.assert_allclose(command.evaluate(0, t), position, atol=1e-13)
    kinks = np.concatenate([train.start_s, train.start_s + train.rise_s])
    assert set(np.round(kinks, 12)) <= set(np.round(command.time_s, 12))
    assert command.peak_abs(2) is None  # the 0.4 step makes the acceleration impulsive
    # max_slope: 1 on [0, 0.7), 1 - 0.6 = 0.4 on [0.7, 1), -0.6 on [1, 1.2), 0.2/0.3 on [2, 2.3)
    assert train.max_slope() == pytest.approx(1.0, rel=1e-14)


def test_shaping_commutes_with_the_ramp_train_and_is_exact_for_any_command():
    shaper = ImpulseSequence(np.array([0.3, 0.5, 0.2]), np.array([0.0, 0.41, 0.83]))
    train = RampTrain(np.array([0.0, 1.5]), np.array([0.6, 0.6]), np.array([2.0, -2.0]))
    by_train = train.shaped(shaper).to_command()
    by_command = shape_command(train.to_command(), shaper)
    t = np.linspace(0.0, 4.0, 3001)
    for m in (0, 1, 2):  # two routes to the same exact piecewise polynomial
        np.testing.assert_allclose(by_command.evaluate(m, t), by_train.evaluate(m, t), atol=1e-12)
    # Any smooth command: sum_i A_i p(t - t_i) evaluated pointwise by the original command.
    grid = np.linspace(0.0, 2.0, 41)
    original = PiecewiseCommand.from_samples(grid, np.sin(3 * grid) ** 2, 2)
    shaped = shape_command(original, shaper)
    expected = sum(a * original.evaluate(1, t - ti) for a, ti in zip(shaper.amplitudes, shaper.times_s, strict=True))
    np.testing.assert_allclose(shaped.evaluate(1, t), expected, atol=1e-12)


def test_shape_samples_are_the_samples_of_the_exact_shaped_command():
    shaper = ImpulseSequence(np.array([0.25, 0.5, 0.25]), np.array([0.0, 0.013, 0.026]))
    t = np.linspace(0.0, 0.2, 201)
    position = np.where(t < 0.1, 0.5 * (1 - np.cos(np.pi * t / 0.1)), 1.0)
    exact = shape_command(PiecewiseCommand.from_samples(t, position, 0), shaper)
    np.testing.assert_allclose(shape_samples(t, position, shaper), exact.evaluate(0, t), atol=1e-14)


def test_vibration_band_of_zv_and_zvd_matches_the_closed_forms():
    # Undamped ZV: V = |cos(pi r/2)| <= 0.05 for r in [2/pi acos(0.05), 2 - that]; ZVD: V = cos^2.
    zv = zv_by_hand(1.0, 0.0)
    low, high = vibration_band(zv, 1.0, 0.0, 0.05, slack=0.0)  # no slack: the exact crossing
    edge = 2 / math.pi * math.acos(0.05)
    assert (low, high) == (pytest.approx(edge, abs=1e-12), pytest.approx(2 - edge, abs=1e-12))
    zvd = convolve(zv, zv)
    low, high = vibration_band(zvd, 1.0, 0.0, 0.05, slack=0.0)
    edge = 2 / math.pi * math.acos(math.sqrt(0.05))
    assert (low, high) == (pytest.approx(edge, abs=1e-12), pytest.approx(2 - edge, abs=1e-12))
    # A threshold the shaper exceeds at the design frequency has no band.
    assert vibration_band(ImpulseSequence(np.array([0.6, 0.4]), np.array([0.0, math.pi])), 1.0, 0.0, 0.05) is None


def test_a_long_ramp_train_is_built_in_bounded_memory():
    # The most ramps input shaping builds: 1000 (MAX_SHAPED_RAMPS) in a pulse, 2000. Its command and slope
    # were (breakpoints x ramps) tables built whole, 4001 x 2000: 138 MiB at the peak (tracemalloc); they are
    # built in chunks of 2 MiB now (8.7 MiB measured), to the same numbers as a direct sum over the ramps.
    import tracemalloc

    rng = np.random.default_rng(3)
    count = 2000
    train = RampTrain(np.sort(rng.uniform(0, 10, count)), rng.uniform(0.01, 0.1, count), rng.normal(0, 1, count))
    tracemalloc.start()
    try:
        command = train.to_command()
        slope = train.max_slope()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 32 * 2**20
    t = command.time_s[::97]
    assert command.evaluate(1, t) == pytest.approx(train.velocity(t), abs=1e-12 * count)
    assert slope == pytest.approx(float(np.max(np.abs(command.derivative(2)))), rel=1e-12)
