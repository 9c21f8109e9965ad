"""Sensitivity curves: one dot product per frequency must equal a full simulation."""

from __future__ import annotations

import numpy as np
import pytest

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.metrics import metrics
from models.plants import ModePlant
from models.pseudo_polynomial import PseudoPolynomial
from models.sensitivity import band_below, sensitivity
from models.simulation import simulate

STAP_40HZ = PiecewiseCommand.from_samples(np.array([0, 0.025, 0.15, 0.175, 0.3]), np.array([0, 1000, 1000, 0, 0.0]), 2)


@pytest.mark.parametrize("zeta", [0.0, 0.1])
def test_sensitivity_equals_simulation_at_every_ratio(zeta):
    ratios = np.array([0.6, 0.9, 1.0, 1.13, 1.7])
    curve = sensitivity(STAP_40HZ, 2 * np.pi * 40, ratios, np.array([zeta]))
    assert curve.quantity == "velocity"
    for ratio, value in zip(ratios, curve.residual[0], strict=True):
        m = metrics(simulate(ModePlant(40 * ratio, zeta), STAP_40HZ))
        # Same quantity by two routes (dot product vs recurrence): agreement to round-off.
        assert value == pytest.approx(m.residual_velocity_amplitude / 150, rel=1e-9, abs=1e-15)


def test_rest_to_rest_sensitivity_is_relative_to_the_displacement():
    t = np.linspace(0, 2, 401)
    pos = np.where(t < 1, 0.5 * (1 - np.cos(np.pi * t)), 1.0) * 3.0
    cmd = PiecewiseCommand.from_samples(t, pos, 0)
    curve = sensitivity(cmd, 2 * np.pi * 2.0, np.array([1.0]), np.array([0.02]))
    assert curve.quantity == "position"
    m = metrics(simulate(ModePlant(2.0, 0.02), cmd))
    assert curve.residual[0, 0] == pytest.approx(m.residual_amplitude / 3.0, rel=1e-9)


def test_band_below_interpolates_the_crossings():
    ratios = np.linspace(0.5, 1.5, 11)
    residual = np.abs(ratios - 1.0)  # crosses 0.05 at 0.95 and 1.05
    low, high = band_below(ratios, residual, 0.05)
    assert (low, high) == (pytest.approx(0.95), pytest.approx(1.05))
    assert band_below(ratios, residual + 0.1, 0.05) is None


def test_resampling_keeps_the_breakpoints_and_the_response():
    fine = STAP_40HZ.resampled(0.001)
    assert set(STAP_40HZ.time_s) <= set(fine.time_s)
    assert np.max(np.diff(fine.time_s)) <= 0.001 + 1e-15
    a = metrics(simulate(ModePlant(37.0), STAP_40HZ)).residual_velocity_amplitude
    b = metrics(simulate(ModePlant(37.0), fine)).residual_velocity_amplitude
    assert b == pytest.approx(a, rel=1e-11)
    awkward = STAP_40HZ.resampled(0.0007)  # breakpoints fall between grid points
    assert set(STAP_40HZ.time_s) <= set(awkward.time_s)
    c = metrics(simulate(ModePlant(37.0), awkward)).residual_velocity_amplitude
    assert c == pytest.approx(a, rel=1e-11)


def test_band_open_at_the_end_of_the_evaluated_range():
    ratios = np.linspace(0.5, 1.5, 11)
    residual = np.where(ratios < 0.8, 0.2, 0.01)  # within 5 % from 0.8 up to the end of the range
    low, high = band_below(ratios, residual, 0.05)
    assert low == pytest.approx(0.7 + 0.1 * 0.15 / 0.19, rel=1e-12) and high is None  # linear crossing


def test_sensitivity_refuses_ratios_where_round_off_dominates():
    # A 2001-sample command (Table III's zero-energy pseudo-polynomial, Hermite velocity hold): at
    # 1e-3 of its 5 Hz mode the sum behind the residual cancels terms far larger than the move.
    law = PseudoPolynomial(30 * np.pi, 1.0, (3.0117026577, 4.766987994, 5.5975007513))
    command = law.command(1e-3, 2.0)
    near_rigid = sensitivity(command, 31.1769, np.array([0.01]), np.array([0.0])).residual[0, 0]
    assert near_rigid == pytest.approx(1.0, abs=0.01)  # a mode 100 times slower barely follows: ~the whole move
    with pytest.raises(InvalidParameter) as info:
        sensitivity(command, 31.1769, np.array([1e-3, 1.0]), np.array([0.0]))
    assert info.value.field == "sensitivity"


def test_the_largest_curve_the_pipeline_allows_is_computed_in_bounded_memory():
    # optim.synthesis admits up to 20 million (frequency, damping, breakpoint) terms (MAX_SENSITIVITY_WORK): here
    # 4001 ratios x 50 damping ratios x 100 breakpoints. The terms are built in chunks: 135 MiB at the peak
    # (tracemalloc) with chunks of 2 million, 29 MiB with 262144; a frequency's sum does not depend on the chunk it
    # falls in (the same ratios evaluated alone give the same residuals).
    import tracemalloc

    from models.shapers import RampTrain

    rng = np.random.default_rng(0)
    command = RampTrain(np.sort(rng.uniform(0, 1, 50)), rng.uniform(0.01, 0.05, 50), rng.normal(0, 1, 50)).to_command()
    ratios, zetas = np.linspace(0.5, 1.5, 4001), np.linspace(0.0, 0.2, 50)
    tracemalloc.start()
    try:
        curve = sensitivity(command, 30.0, ratios, zetas)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 64 * 2**20
    assert curve.residual.shape == (50, 4001)
    single = sensitivity(command, 30.0, ratios[:7], zetas[:1])
    assert curve.residual[0, :7] == pytest.approx(single.residual[0], rel=1e-12)
