"""Sampled commands as piecewise polynomials."""

from __future__ import annotations

import numpy as np
import pytest

from models.commands import PiecewiseCommand, check_time_grid
from models.errors import InvalidParameter


def test_linear_hold_on_acceleration_integrates_a_cubic_exactly():
    # p(t) = t^3 - 2 t^2 has a linear acceleration 6 t - 4: a first-order hold describes it
    # exactly, so the integrals must equal the closed form to round-off.
    t = np.sort(np.concatenate([[0.0, 2.0], np.random.default_rng(3).uniform(0, 2, 50)]))
    cmd = PiecewiseCommand.from_samples(t, 6 * t - 4, 2)
    np.testing.assert_allclose(cmd.derivative(0), t**3 - 2 * t**2, rtol=0, atol=1e-13)
    np.testing.assert_allclose(cmd.derivative(1), 3 * t**2 - 4 * t, rtol=0, atol=1e-13)
    np.testing.assert_allclose(cmd.derivative(3)[:-1], 6.0, rtol=1e-12)
    dense = np.linspace(0, 2, 333)
    np.testing.assert_allclose(cmd.evaluate(0, dense), dense**3 - 2 * dense**2, atol=1e-12)


def test_initial_values_and_zero_hold():
    t = np.array([0.0, 1.0, 3.0])
    cmd = PiecewiseCommand.from_samples(t, np.array([2.0, -1.0, 0.0]), 1, hold="zero", initial=(5.0,))
    # position: 5, 5 + 2*1 = 7, 7 - 1*2 = 5
    np.testing.assert_allclose(cmd.derivative(0), [5.0, 7.0, 5.0])
    assert cmd.degree == 1
    jumps = cmd.jumps()
    np.testing.assert_allclose(jumps[1], [2.0, -3.0, 1.0])  # the held velocity's steps
    assert cmd.end_index() == 2
    assert cmd.peak_abs(1) == 2.0
    assert cmd.peak_abs(2) is None  # the velocity jumps: the acceleration is impulsive


def test_peak_inside_a_piece_is_found():
    # Acceleration 1 -> -1 over [0, 2]: the velocity t - t^2/2 peaks at t = 1 with 0.5 between samples.
    cmd = PiecewiseCommand.from_samples(np.array([0.0, 2.0]), np.array([1.0, -1.0]), 2)
    assert cmd.peak_abs(1) == pytest.approx(0.5, rel=1e-15)
    assert cmd.peak_abs(2) == 1.0
    assert cmd.peak_abs(3) is None  # starts from rest with a = 1: the jerk is impulsive at t_0
    assert cmd.peak_abs(0) == pytest.approx(2 * 2 / 2 - 8 / 6, rel=1e-15)  # p(2) = t^2/2 - t^3/6


def test_end_index_ignores_the_flat_tail():
    t = np.linspace(0, 2, 201)
    acc = np.where(t < 1, np.sin(np.pi * t), 0.0)
    cmd = PiecewiseCommand.from_samples(t, acc, 2)
    # sin(pi t) reaches 0 at the sample t = 1, where the acceleration slope changes for the last time.
    assert cmd.time_s[cmd.end_index()] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize(
    ("times", "field"),
    [
        ([0.0], "time_s"),
        ([0.0, 1.0, 1.0], "time_s[2]"),
        ([0.0, 2.0, 1.0], "time_s[2]"),
        ([0.0, float("nan")], "time_s"),
    ],
)
def test_bad_time_grids(times, field):
    with pytest.raises(InvalidParameter) as info:
        check_time_grid(np.array(times))
    assert info.value.field == field
