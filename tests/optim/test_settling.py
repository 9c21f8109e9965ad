"""Settling with a vibration criterion (issue 11, section 1), checked per family against an independent
computation: the free oscillation left at the command's end from ``scipy.signal.lsim`` of the densely
sampled command, whose envelope A exp(-sigma t) crosses the tighter band at t = ln(A / band) / sigma."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import signal

from models.commands import PiecewiseCommand
from models.metrics import metrics, vibration_envelope
from models.plants import make_plant
from models.simulation import simulate
from optim.problem import Limits, Problem
from optim.registry import FAMILIES
from optim.synthesis import evaluate

NOMINAL = make_plant("mode", natural_frequency_hz=5.0, damping_ratio=0.05)
LIMITS = Limits(max_velocity=2.0, max_acceleration=20.0)
CASES = [
    ("pseudo_polynomial", "displacement"),
    ("stap", "displacement"),
    ("stap", "target_velocity"),
    ("smoother", "displacement"),
    ("input_shaped", "displacement"),
    ("input_shaped", "target_velocity"),
]


def designed(name: str, move: str):
    family = FAMILIES[name]
    problem = Problem(NOMINAL, **{move: 1.0}, limits=LIMITS)
    return family, problem, family.design(problem, family.default_options(problem))


def free_amplitude_by_lsim(command: PiecewiseCommand, hz: float, zeta: float, velocity: bool) -> float:
    """Amplitude of the load's free oscillation about its final motion when the command ends (lsim on 20000
    linear pieces per second of the exact command: its error, ~(h w)^2, is far below the 1e-6 tolerance)."""
    w = 2 * math.pi * hz
    end = float(command.time_s[command.end_index()])
    t = np.linspace(float(command.time_s[0]), end, int(20000 * end) + 2)
    u = command.evaluate(0, t)
    system = signal.lti([2 * zeta * w, w * w], [1.0, 2 * zeta * w, w * w])
    _, y, x = signal.lsim(system, u, t)
    a, b, c, _ = signal.tf2ss([2 * zeta * w, w * w], [1.0, 2 * zeta * w, w * w])
    state = x[-1]
    rate = float((c @ (a @ state + b[:, 0] * u[-1]))[0]) + 0.0  # load velocity at the end (D = 0)
    error = y[-1] - u[-1]
    rate_error = rate - float(command.evaluate(1, np.array([end]))[0])
    sigma, wd = zeta * w, w * math.sqrt(1 - zeta * zeta)
    if velocity:  # the velocity oscillation: differentiate the free response e = A e^(-st) cos(...)
        accel_error = -2 * sigma * rate_error - w * w * error
        error, rate_error = rate_error, accel_error
    return math.hypot(error, (rate_error + sigma * error) / wd)


@pytest.mark.parametrize(("name", "move"), CASES)
def test_settling_is_null_on_an_undamped_mode_left_ringing(name, move):
    family, problem, design = designed(name, move)
    detuned = dataclasses.replace(problem, plant=make_plant("mode", natural_frequency_hz=6.37, damping_ratio=0.0))
    result = evaluate(family, detuned, design)
    window = result.metrics.settling.vibration_window
    assert result.metrics.residual_amplitude + result.metrics.residual_velocity_amplitude > 2 * window
    assert result.metrics.settling.time_s is None


@pytest.mark.parametrize(("name", "move"), CASES)
def test_settling_is_where_the_exact_envelope_crosses_the_tighter_band(name, move):
    family, problem, design = designed(name, move)
    hz, zeta = 6.37, 0.05  # the true mode 27 % above the design's: a residual the family did not cancel
    detuned = dataclasses.replace(problem, plant=make_plant("mode", natural_frequency_hz=hz, damping_ratio=zeta))
    result = evaluate(family, detuned, design)
    w = 2 * math.pi * hz
    velocity = move == "target_velocity"
    # The defaults of the issue: 1e-3 of the load's move; 1 % of a / w^2 (a / w for a velocity).
    position_band = 1e-3 * 1.0
    vibration_band = 0.01 * LIMITS.max_acceleration / (w if velocity else w * w)
    band = min(position_band, vibration_band)
    amplitude = free_amplitude_by_lsim(result.command, hz, zeta, velocity)
    assert amplitude > 2 * band  # the residual is well above the band: settling is after the end
    expected = result.metrics.command_end_s + math.log(amplitude / band) / (zeta * w)
    assert result.metrics.settling.vibration_window == pytest.approx(vibration_band, rel=1e-12)
    # 1e-6 s: the lsim amplitude's relative error (~1e-7) over sigma = 1.9 1/s.
    assert result.metrics.settling.time_s == pytest.approx(expected, abs=1e-6)


def test_a_two_mode_plant_with_an_undamped_mode_never_settles():
    # Today's bug: 1.87e14 s. (s^2 + 2 z w1 s + w1^2)(s^2 + w2^2), unit DC gain, a plain ramp left ringing.
    w1, w2 = 2 * math.pi * 3.0, 2 * math.pi * 11.0
    den = np.polymul([1.0, 2 * 0.1 * w1, w1 * w1], [1.0, 0.0, w2 * w2])
    plant = make_plant("transfer_function", numerator=[w1 * w1 * w2 * w2], denominator=list(den))
    command = PiecewiseCommand.from_samples([0.0, 0.5, 1.0], [0.0, 1.0, 1.0], 0)
    result = metrics(simulate(plant, command))
    assert result.residual_amplitude > 1e-3
    assert result.settling.time_s is None


def test_settling_can_come_before_the_command_ends():
    # The load is within both bands at t = 0.6 s; the command's last change (1e-7 at t = 1.5 s) is
    # far inside them: settling is at the first sample after the last one outside, before the end.
    plant = make_plant("mode", natural_frequency_hz=50.0, damping_ratio=0.5)
    t = np.linspace(0.0, 1.5, 1501)
    position = np.clip(t / 0.5, 0.0, 1.0) + np.where(t >= 1.5, 1e-7, 0.0)
    response = simulate(plant, PiecewiseCommand.from_samples(t, position, 0))
    result = metrics(response, 1e-3, vibration_window=1e-4)
    assert result.command_end_s == pytest.approx(1.5)
    assert 0.5 < result.settling.time_s < 0.7
    outside = (np.abs(response.load_position - 1.0) > 1e-3) | (vibration_envelope(response, 0) > 1e-4)
    assert not np.any(outside[t >= result.settling.time_s])
    assert outside[np.searchsorted(t, result.settling.time_s) - 1]


def test_the_envelope_during_a_constant_acceleration_is_the_quasi_static_deflection():
    # Constant acceleration a on one undamped mode started smoothly enough that the free part is tiny:
    # the load lags by a / w^2 (the particular solution of e'' + w^2 e = -a).
    w = 2 * math.pi * 4.0
    plant = make_plant("mode", natural_frequency_hz=4.0, damping_ratio=0.0)
    command = PiecewiseCommand.from_samples([0.0, 10.0], [3.0, 3.0], 3 - 1, hold="zero")  # a = 3 throughout
    response = simulate(plant, command)
    envelope = vibration_envelope(response, 0)
    free = 3.0 / (w * w)  # the start from rest excites an oscillation of amplitude a / w^2 as well
    assert envelope[0] == pytest.approx(free + 3.0 / (w * w), rel=1e-12)
