"""The drive's rate limiter and position-mode follower (models.drives), against a sample-by-sample limiter,
a sample-by-sample position loop and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.commands import PiecewiseCommand
from models.drives import catch_up_plan, follow_position, rate_limit
from models.errors import InvalidParameter
from models.shapers import ImpulseSequence, RampTrain
from tests.shaper_oracle import discrete_rate_limiter


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
