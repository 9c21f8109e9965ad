"""The exact motor-torque peak of piecewise-constant-acceleration commands (models.torque): against the closed
form of an undamped two-inertia plant under one ramp, and against dense sampling of the exact simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.commands import PiecewiseCommand
from models.plants import ModePlant, TwoInertiaPlant
from models.shapers import RampTrain
from models.simulation import simulate
from models.torque import peak_motor_torque_nm


def ramp_peak(j_m: float, j_l: float, omega: float, accel: float, ramp_s: float) -> float:
    """Undamped two-inertia plant, motor acceleration ``accel`` for ``ramp_s`` from rest, then none. From
    J_L y'' = k (p - y) with e = y - p: e'' + omega^2 e = -a, so y'' = a (1 - cos omega tau) during the ramp
    (torque J_M a + J_L a (1 - cos omega tau), largest at the ramp's end or, past half a period, 2 J_L a above
    the inertial part), and afterwards a free oscillation of amplitude 2 J_L a |sin(omega T / 2)|."""
    during = 2.0 if omega * ramp_s >= math.pi else 1.0 - math.cos(omega * ramp_s)
    return max(j_m * accel + j_l * accel * during, 2.0 * j_l * accel * abs(math.sin(0.5 * omega * ramp_s)))


@pytest.mark.parametrize("periods", [0.1, 0.3, 0.5, 0.77, 1.0, 2.25, 40.5])
def test_one_ramp_on_an_undamped_shaft_matches_the_closed_form(periods):
    j_m, j_l, k = 0.002, 0.01, 43_000.0
    plant = TwoInertiaPlant(j_m, j_l, k)
    omega = math.sqrt(k / j_l)
    ramp_s = periods * 2.0 * math.pi / omega
    velocity = 3.0
    command = RampTrain.single(0.0, ramp_s, velocity).to_command()
    expected = ramp_peak(j_m, j_l, omega, velocity / ramp_s, ramp_s)
    assert peak_motor_torque_nm(plant, command) == pytest.approx(expected, rel=1e-9)


def dense_peak(plant: TwoInertiaPlant, command: PiecewiseCommand, per_period: int) -> float:
    """max |torque| of the exact simulation on a uniform grid of ``per_period`` samples per period, with every
    breakpoint and a sample 1e-8 s before each (its left limit, where the acceleration jumps), to 20 periods
    past the end (the undamped oscillation repeats; a damped one only decays)."""
    period = plant.modes()[0].natural_period_s
    end = float(command.time_s[-1]) + 20.0 * period
    grid = np.arange(0.0, end, period / per_period)
    t = np.union1d(np.union1d(grid, command.time_s), command.time_s[1:] - 1e-8)
    sampled = PiecewiseCommand(t, command._evaluate_orders(t), command.continuous_orders)
    torque = simulate(plant, sampled).motor_torque_nm
    assert torque is not None
    return float(np.max(np.abs(torque)))


def test_random_ramp_trains_match_dense_sampling():
    # 16 seeded random trains of ramps (the shapes input shaping makes) on random, damped or undamped, shafts.
    # The dense grid's peak is below the true one by at most the curvature between samples,
    # (pi / 4000)^2 / 2 = 3.1e-7 of the oscillation, and by |T'| 1e-8 s at a left limit (< 1e-5 rad here).
    rng = np.random.default_rng(7)
    for trial in range(16):
        plant = TwoInertiaPlant(
            float(10 ** rng.uniform(-3, -1)),
            float(10 ** rng.uniform(-3, -1)),
            float(10 ** rng.uniform(0, 3)),
            float(rng.uniform(0.0, 0.02)) if trial % 2 else 0.0,
        )
        n = int(rng.integers(1, 6))
        command = RampTrain(rng.uniform(0, 1, n), rng.uniform(0.01, 0.5, n), rng.normal(0, 1, n)).to_command()
        exact = peak_motor_torque_nm(plant, command)
        dense = dense_peak(plant, command, 4000)
        assert dense <= exact * (1 + 1e-12), trial
        assert exact <= dense * (1 + 2e-6), trial


def test_a_critical_point_inside_a_short_piece_counts():
    # Two ramps whose kink falls mid-swing: the largest torque is inside the second piece, away from every
    # breakpoint, so a check at the breakpoints alone (or only the first critical point) would miss it.
    plant = TwoInertiaPlant(0.001, 0.01, 1000.0, 0.01)
    period = plant.modes()[0].natural_period_s
    command = RampTrain(
        np.array([0.0, 0.3 * period]), np.array([0.3 * period, 1.9 * period]), np.array([1.0, -0.4])
    ).to_command()
    at_breakpoints = float(np.max(np.abs(simulate(plant, command).motor_torque_nm)))
    exact = peak_motor_torque_nm(plant, command)
    assert exact > 1.01 * at_breakpoints
    assert exact == pytest.approx(dense_peak(plant, command, 4000), rel=2e-6)


def test_the_work_does_not_grow_with_the_frequency():
    # The 11 s ramp of issue 23's reproducer (330 Hz) and a 1000 times stiffer shaft (10.4 kHz): the peak comes
    # from the command's breakpoints (2 here), where 2000 samples per period needed 7.3 million and 230 million.
    for k in (43_000.0, 43_000_000.0):
        plant = TwoInertiaPlant(0.001, 0.01, k)
        command = RampTrain.single(0.0, 11.0, 100.0).to_command()
        assert command.time_s.size == 2
        omega = math.sqrt(k / 0.01)
        assert peak_motor_torque_nm(plant, command) == pytest.approx(ramp_peak(0.001, 0.01, omega, 100 / 11, 11.0))


def test_no_torque_without_inertias_and_an_impulse_for_a_velocity_step():
    ramp = RampTrain.single(0.0, 0.1, 1.0).to_command()
    assert peak_motor_torque_nm(ModePlant(5.0, 0.01), ramp) is None
    step = RampTrain.single(0.0, 0.0, 1.0).to_command()
    assert peak_motor_torque_nm(TwoInertiaPlant(0.001, 0.01, 1000.0), step) == math.inf
