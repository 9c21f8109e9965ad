"""Impulse sequences, V(omega, zeta), shaped and rate-limited commands (models.shapers).

Expected values come from independent routes: exact simulation of a mode plant
(tests.shaper_oracle.v_by_simulation), closed-form integrals written out here, the undamped
closed forms of V, and a sample-by-sample rate limiter.
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
    catch_up_plan,
    convolve,
    follow_position,
    percentage_vibration,
    rate_limit,
    shape_command,
    shape_samples,
    vibration_band,
)
from models.simulation import simulate
from tests.shaper_oracle import discrete_rate_limiter, v_by_simulation

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


def dense_limited(command: PiecewiseCommand, limit: float, end: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The discrete limiter's output sampled every dt."""
    t = np.arange(0.0, end, dt)
    return t, discrete_rate_limiter(command.evaluate(1, t), dt, limit)


@pytest.mark.parametrize(
    "train",
    [
        # the ZVD-shaped unit step of the paper (Fig. 6): a staircase the limiter turns into ramps
        RampTrain(np.array([0.0, 5.4535, 10.9071]), np.zeros(3), np.array([0.2973, 0.4959, 0.2068])),
        # a steep ramp (slope 0.5 > a) then a gentle one (0.05 < a), then down again: chase, follow, fall
        RampTrain(np.array([0.0, 3.0, 9.0]), np.array([2.0, 10.0, 0.0]), np.array([1.0, 0.5, -1.5])),
        # a short pulse that the limiter cannot follow (up and down before catching up)
        RampTrain(np.array([0.0, 2.0]), np.zeros(2), np.array([1.0, -1.0])),
    ],
)
def test_rate_limiter_matches_a_sample_by_sample_limiter(train):
    a = 0.1
    command = train.to_command()
    limited = rate_limit(command, a)
    t, reference = dense_limited(command, a, 40.0, 1e-3)
    # The sample-by-sample limiter starts each chase up to one step late, a lag of a dt = 1e-4 in
    # velocity per chase (measured: at most 2e-4 here); 3e-4 allows that and still catches a
    # meeting time off by 3 ms or more. Slopes and the final value are checked exactly below.
    np.testing.assert_allclose(limited.evaluate(1, t), reference, atol=3e-4)
    slopes = limited.derivative(2)
    assert np.max(np.abs(slopes)) <= a * (1 + 1e-12)
    assert limited.evaluate(1, np.array([1e3]))[0] == pytest.approx(train.final_velocity, abs=1e-12)


def test_rate_limiter_meeting_times_are_exact():
    # Staircase 0.3 at 0, +0.5 at 5: the drive ramps at 0.1 and meets 0.3 at t = 3 exactly, then
    # meets 0.8 at t = 5 + 0.5/0.1 = 10 (closed form of the chase).
    train = RampTrain(np.array([0.0, 5.0]), np.zeros(2), np.array([0.3, 0.5]))
    limited = rate_limit(train.to_command(), 0.1)
    np.testing.assert_allclose(limited.time_s, [0.0, 3.0, 5.0, 10.0], atol=1e-12)
    np.testing.assert_allclose(limited.derivative(2), [0.1, 0.0, 0.1, 0.0], atol=1e-15)
    # Position: the integral of the velocity 0.1 t (to 3), 0.3, then 0.3 + 0.1 (t - 5): 0.45, 1.05, 3.8
    np.testing.assert_allclose(limited.derivative(0), [0.0, 0.45, 1.05, 3.8], atol=1e-12)


def test_a_command_within_the_limit_passes_unchanged():
    # slopes 0.05 and 0.04 (overlapping on [1, 2): 0.09), then -0.08: all within a = 0.1
    train = RampTrain(np.array([0.0, 1.0, 4.0]), np.array([2.0, 3.0, 1.0]), np.array([0.1, 0.12, -0.08]))
    command = train.to_command()
    limited = rate_limit(command, 0.1)
    t = np.linspace(0.0, 8.0, 4001)
    for m in (0, 1, 2):  # exact both: equal to round-off
        np.testing.assert_allclose(limited.evaluate(m, t), command.evaluate(m, t), atol=1e-14)


def test_rate_limiter_refuses_a_bad_limit():
    with pytest.raises(InvalidParameter) as info:
        rate_limit(RampTrain.single(0.0, 0.0, 1.0).to_command(), -0.1)
    assert info.value.field == "acceleration_limit"


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


# ------------------------------------------------------------------------------------------
# The position-mode drive: a time-optimal follower of the shaped position reference


def square_root_follower(reference, dt: float, end_s: float, accel: float, top: float) -> tuple:
    """A drive's sample-by-sample position loop (reference only, shares nothing with follow_position):
    each sample it asks for the closing speed sign(e) sqrt(2 a |e|) from which it can still brake onto
    the reference, within |a| <= accel and |v| <= top, with forward-Euler steps of dt."""
    t = np.arange(0.0, end_s, dt)
    p_ref, v_ref = reference.evaluate(0, t), reference.evaluate(1, t)
    p = np.empty_like(t)
    v = np.empty_like(t)
    pos, vel = float(p_ref[0]), 0.0
    for k in range(t.size):  # the drive's loop (reference only)
        p[k], v[k] = pos, vel
        gap = p_ref[k] - pos
        wanted = math.copysign(math.sqrt(2.0 * accel * abs(gap)), gap) + v_ref[k]
        new = min(max(vel + min(max((wanted - vel) / dt, -accel), accel) * dt, -top), top)
        pos += 0.5 * (vel + new) * dt
        vel = new
    return t, p, v


def pulse_reference(shaper: ImpulseSequence, displacement: float, velocity: float) -> PiecewiseCommand:
    return RampTrain.single(0.0, 0.0, velocity).pulse(displacement / velocity).shaped(shaper).to_command()


def test_catch_up_from_rest_is_the_textbook_bang_bang_and_trapezoid():
    # From rest onto a target at rest D = 2 with a = 8: a triangle of 2 sqrt(D/a) = 1 s peaking at
    # sqrt(a D) = 4; with |v| <= 2, a trapezoid of D/v + v/a = 1.25 s (closed forms).
    triangle = catch_up_plan(2.0, 0.0, 0.0, 8.0, math.inf)
    assert [d for d, _ in triangle] == pytest.approx([0.5, 0.5], rel=1e-15)
    assert [u for _, u in triangle] == [8.0, -8.0]
    trapezoid = catch_up_plan(2.0, 0.0, 0.0, 8.0, 2.0)
    assert [d for d, _ in trapezoid] == pytest.approx([0.25, 0.75, 0.25], rel=1e-15)
    assert sum(d for d, _ in trapezoid) == pytest.approx(2.0 / 2.0 + 2.0 / 8.0, rel=1e-15)


@pytest.mark.parametrize("seed", range(5))
def test_catch_up_lands_on_a_moving_target(seed):
    # Random state and target velocity: integrating the phases by hand lands on the target (gap and
    # relative velocity zero up to round-off, 1e-12 of the scales), within both limits.
    rng = np.random.default_rng(seed)
    gap, velocity, target_v = rng.uniform(-1, 1), rng.uniform(-2, 2), rng.uniform(-1.5, 1.5)
    accel, top = rng.uniform(0.5, 5.0), 2.0
    position, v, target = 0.0, velocity, gap
    for duration, u in catch_up_plan(gap, velocity, target_v, accel, top):
        assert abs(u) <= accel and duration >= 0.0
        position += v * duration + 0.5 * u * duration**2
        v += u * duration
        target += target_v * duration
        assert abs(v) <= top * (1 + 1e-12)
    assert position == pytest.approx(target, abs=1e-12)
    assert v == pytest.approx(target_v, abs=1e-12)


@pytest.mark.parametrize(("cruise", "top"), [(0.8398186636994082, math.inf), (0.5, 0.55)])
def test_position_follower_arrives_within_the_limits_and_matches_a_drive_loop(cruise, top):
    # The reproducer (40.04 Hz, zeta 0.0856, ZVD, D = -0.013555, a = 32.899) with the pulse at
    # 0.83982 (the single-ramp cruise), or at 0.5 with |v| <= 0.55 (the catch-ups then coast at the
    # limit): the shaped staircase breaks the acceleration limit; the follower arrives.
    omega, zeta = 2 * math.pi * 40.03893781783215, 0.08560034273978648
    k = math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    half = math.pi / (omega * math.sqrt(1 - zeta**2))
    zvd = ImpulseSequence(np.array([1.0, 2 * k, k * k]) / (1 + k) ** 2, np.array([0.0, half, 2 * half]))  # eqs. 8-11
    displacement, accel = -0.01355515198087977, 32.89918298569201
    reference = pulse_reference(zvd, displacement, -cruise)
    out = follow_position(reference, accel, None if math.isinf(top) else top)
    # It arrives at rest: exact (round-off of a few dozen pieces).
    assert out.derivative(0)[-1] == pytest.approx(displacement, rel=1e-12)
    assert out.derivative(1)[-1] == pytest.approx(0.0, abs=1e-12)
    # Within the limits: exact peaks (piecewise-constant acceleration) and finite differences.
    assert np.max(np.abs(out.derivative(2))) <= accel * (1 + 1e-12)
    assert out.peak_abs(1) <= top * (1 + 1e-12)
    if math.isfinite(top):
        assert out.peak_abs(1) == pytest.approx(top, rel=1e-12)  # the limit binds: some catch-up coasts at it
    # A sample-by-sample square-root position loop (dt = 1e-6 s) follows the same path: it lags each
    # chase by about a sample (measured: at most 1.7e-6 and 9.5e-7 apart); 1e-5 (0.07 % of the move)
    # allows that lag.
    t, p, _ = square_root_follower(reference, 1e-6, float(out.time_s[-1]) + 0.01, accel, top)
    np.testing.assert_allclose(out.evaluate(0, t), p, atol=1e-5)
    # ... and ends where it does.
    assert p[-1] == pytest.approx(displacement, abs=1e-8)


def test_position_follower_passes_a_reference_it_can_follow():
    # A staircase of velocities 0.1 then 0.3 (steps 0.1 and 0.2) with a = 1e3: each chase lasts 0.1 or
    # 0.2 ms, the follower is back on the reference right after, and its final position is the reference's.
    reference = RampTrain(np.array([0.0, 1.0, 2.0]), np.zeros(3), np.array([0.1, 0.2, -0.3])).to_command()
    out = follow_position(reference, 1e3)
    t = np.linspace(0.01, 3.0, 301)
    lag = out.evaluate(0, t) - reference.evaluate(0, t)
    # After each 0.1 ms catch-up the lag is zero (round-off); inside one it is at most v^2/(2a) = 2e-5.
    assert np.max(np.abs(lag[t > 2.01])) < 1e-14
    assert np.max(np.abs(lag)) < 1e-14 + 2e-5
    assert out.derivative(0)[-1] == pytest.approx(0.1 + 0.3, rel=1e-14)


def test_position_follower_refuses_a_ramp_reference_or_one_above_the_velocity_limit():
    with pytest.raises(InvalidParameter):
        follow_position(RampTrain.single(0.0, 1.0, 1.0).to_command(), 1.0)
    with pytest.raises(InvalidParameter) as info:
        follow_position(RampTrain.single(0.0, 0.0, 1.0).to_command(), 1.0, 0.5)
    assert info.value.field == "velocity_limit"


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
