"""Issue 11: STAP limits hold for the real motor torque, and the optimiser keeps the closed form when
no solve meets the limits and beats it."""

from __future__ import annotations

import numpy as np
import pytest

from models.plants import TwoInertiaPlant
from models.simulation import simulate
from models.stap_torque import peak_motor_torque_nm
from optim.families import stap as S
from optim.families.stap.moves import closed_form

# The audit's reproducer (issue 11, section 3): a 200 with torque 71.6956 > 71.6677 N m (method optimized).
AUDIT_PLANT = TwoInertiaPlant(0.43113191982048643, 0.7689037090974283, 2693.50111016888, 26.490867301436257)
AUDIT = S.StapRequest(
    AUDIT_PLANT,
    target_velocity=11.391022289965264,
    displacement=4.132450061901825,
    max_torque_nm=71.66772219485838,
)
# Found by a seeded search: zeta = 0.3, k_j = 1, u = 0; eqs. (19), (57)-(59) let the real torque peak 5.8 % over M.
DAMPED_PLANT = TwoInertiaPlant(0.1920713364551599, 0.3745460301194364, 120.08333832276699, 4.023881901202042)
DAMPED = S.StapRequest(
    DAMPED_PLANT, target_velocity=27.124961847760964, max_torque_nm=38.123057442281294, jerk_periods=1,
    frequency_uncertainty=0.0,
)  # fmt: skip


def dense_peak(plant: TwoInertiaPlant, command, period_s: float = 1e-6, tail_s: float = 0.4) -> float:
    """An independent peak: the exact simulation sampled every microsecond (a sampled peak is a lower
    bound; a sinusoid's sampled peak misses at most (omega h)^2 / 2 = 2e-9 of it at 7.5 Hz)."""
    response = simulate(plant, command.resampled(period_s, end_s=float(command.time_s[-1]) + tail_s))
    torque = response.motor_torque_nm
    assert torque is not None
    return float(np.max(np.abs(torque)))


def test_exact_torque_peak_agrees_with_microsecond_sampling():
    design = closed_form(S.check_request(AUDIT))
    command = design.move.command()
    exact = peak_motor_torque_nm(AUDIT_PLANT, command)
    dense = dense_peak(AUDIT_PLANT, command)
    # The closed form's exact peak is 70.9605 N m (issue 11 measured the optimised one); the dense samples
    # lie below it by the sampling loss only (< 1e-9 relative, see dense_peak).
    assert dense <= exact * (1 + 1e-12)
    assert exact == pytest.approx(dense, rel=1e-9)


def test_the_closed_form_is_lowered_until_the_real_torque_fits():
    raw = closed_form(S.check_request(DAMPED))
    raw_peak = peak_motor_torque_nm(DAMPED_PLANT, raw.stap.command())
    assert raw_peak > 1.05 * DAMPED.max_torque_nm  # the eq. (57)-(59) rule alone breaks the limit (zeta = 0.3)
    design = S.design(DAMPED)
    peak = dense_peak(DAMPED_PLANT, design.stap.command())
    # Independent check: the returned command's torque, simulated at 1 us, stays within M (to round-off).
    assert peak <= DAMPED.max_torque_nm * (1 + 1e-12)
    assert design.peak_torque_nm == pytest.approx(peak, rel=1e-9)
    # The 1-D search stops within 1e-7 of the best cap, so the torque is used to within about that
    # (1e-6 leaves room for the peak's slope in the acceleration).
    assert design.peak_torque_nm >= DAMPED.max_torque_nm * (1 - 1e-6)
    assert abs(design.stap.peak_acceleration) < abs(raw.stap.peak_acceleration)
    assert design.stap.jerk_time_s == pytest.approx(raw.stap.jerk_time_s, rel=1e-12)  # k_j = 1 still: t_j = 1/f_n,e
    assert design.torque_lowered_acceleration is not None
    assert any("real motor torque" in n for n in design.notes)


def test_optimized_audit_reproducer_meets_the_torque_limit():
    closed = S.design(AUDIT)
    optimised = S.optimize(AUDIT, closed)
    command = (optimised.move or closed.move).command()
    # Before the fix: 71.6956 N m > 71.6677 N m (issue 11). The real torque now stays within M.
    assert dense_peak(AUDIT_PLANT, command) <= AUDIT.max_torque_nm * (1 + 1e-12)
    assert peak_motor_torque_nm(AUDIT_PLANT, command) <= AUDIT.max_torque_nm * (1 + 1e-12)


def test_a_zero_residual_start_is_kept_not_a_solver_failure():
    # Fig. 17's side band with method optimized: the start already has zero residual, IPOPT stops with
    # Search_Direction_Becomes_Too_Small (a solver-failed answer before issue 11). The closed form is kept.
    plant = TwoInertiaPlant(0.005, 0.005, 0.005 * (2 * np.pi * 40.0) ** 2, 0.0)
    request = S.StapRequest(
        plant, target_velocity=150.0, max_acceleration=1000.0, acceleration_time_s=0.165, jerk_periods=0, delta=1
    )
    closed = S.design(request)
    kept = S.optimize(request, closed)
    assert kept.selection == "closed_form_kept"
    assert kept.stap == closed.stap
    assert "did not improve on the closed-form design" in kept.notes[0]


def test_infeasible_problem_detected_is_not_a_verdict():
    # A seeded search found IPOPT reporting Infeasible_Problem_Detected (answered as solver-failed) here,
    # although the closed form meets the limits. Its residual is zero, the residual objective's minimum,
    # so no solve is run at all now: the closed form is returned and the note says why.
    plant = TwoInertiaPlant(0.010069321718657513, 0.012343861644508411, 45.327447703902216, 0.0)
    request = S.StapRequest(plant, target_velocity=33.16335105143133, max_torque_nm=0.6929462548917136)
    closed = S.design(request)
    kept = S.optimize(request, closed)
    assert kept.selection == "closed_form_kept"
    assert "no solve was run" in kept.notes[0] and kept.solves == 0
    assert peak_motor_torque_nm(plant, kept.stap.command()) <= request.max_torque_nm * (1 + 1e-12)


def test_exact_torque_peak_bounds_a_long_cruise_tightly():
    # Table 2 (8 Hz, J_L = J_M, undamped) at 1 rad/s over 9 rad: a 9 s cruise, 72 periods, longer than the
    # 64 sampled whole; it is sampled over 2 periods and bounded after, which is exact for an undamped mode
    # (the free vibration keeps its amplitude). Independent: 10 us samples of the whole move, whose loss is
    # at most (omega h)^2 / 2 = 1.3e-7 of the oscillation.
    plant = TwoInertiaPlant(0.005, 0.005, 12.63309363339438, 0.0)
    request = S.StapRequest(plant, target_velocity=1.0, displacement=9.0, max_torque_nm=10.0, jerk_periods=1)
    command = S.design(request).move.command()
    assert command.time_s[-1] > 9.0
    exact = peak_motor_torque_nm(plant, command)
    assert exact == pytest.approx(dense_peak(plant, command, period_s=1e-5), rel=1e-6)
