"""The STAP motion law (Cusimano eqs. 9-18), its residual, Appendix B and eqs. (57)-(59)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.metrics import metrics
from models.plants import ModePlant, TwoInertiaPlant
from models.simulation import simulate
from models.stap import (
    RestToRest,
    Stap,
    exciting_term_u,
    load_acceleration_oscillation,
    motor_torque_oscillation,
    motor_torque_scale,
    rectangle_sensitivity,
    sensitivity_appendix_b,
    stap_sensitivity,
)
from models.stap_design import decimal_part
from tests.oracle import ivp_response

SEC3 = Stap(150.0, 0.175, 0.025)  # Sec. 3, Fig. 14: v = 150 rad/s, k_j = 1 at 40 Hz


def test_corners_and_values_of_the_motion_law():
    # Eqs. (11) and (16) by hand: a_max = 150/0.15 = 1000, jerk = 1000/0.025 = 40000.
    assert SEC3.peak_acceleration == pytest.approx(1000.0, rel=1e-15)
    assert SEC3.jerk == pytest.approx(40000.0, rel=1e-15)
    assert SEC3.constant_acceleration_time_s == pytest.approx(0.125, rel=1e-15)
    assert SEC3.shape == "trapezoid"
    # Eqs. (14) and (17): c_a,v = 1/(1 - 1/7) = 7/6, c_j,v = 1/((1/7)(6/7)) = 49/6.
    assert SEC3.acceleration_coefficient == pytest.approx(7 / 6, rel=1e-14)
    assert SEC3.jerk_coefficient == pytest.approx(49 / 6, rel=1e-14)
    cmd = SEC3.command()
    np.testing.assert_allclose(cmd.time_s, [0.0, 0.025, 0.15, 0.175], rtol=0, atol=1e-15)
    # Independent integration of the trapezoid by hand: v(t_j) = a t_j / 2 = 12.5,
    # p(t_j) = j t_j^3 / 6, p(t_a) = v t_a / 2 (symmetry), the acceleration continuous.
    np.testing.assert_allclose(cmd.derivative(1), [0.0, 12.5, 137.5, 150.0], rtol=1e-14)
    np.testing.assert_allclose(cmd.derivative(2), [0.0, 1000.0, 1000.0, 0.0], rtol=1e-14, atol=1e-10)
    np.testing.assert_allclose(cmd.derivative(3), [40000.0, 0.0, -40000.0, 0.0], rtol=1e-14)
    assert cmd.derivative(0)[1] == pytest.approx(40000 * 0.025**3 / 6, rel=1e-14)
    assert cmd.derivative(0)[3] == pytest.approx(150 * 0.175 / 2, rel=1e-15)
    # After t_a the velocity is held: the command continues at 150 rad/s.
    assert cmd.evaluate(1, np.array([0.5]))[0] == pytest.approx(150.0, rel=1e-14)
    assert cmd.evaluate(0, np.array([0.5]))[0] == pytest.approx(150 * 0.175 / 2 + 150 * (0.5 - 0.175), rel=1e-14)
    # The corners are the only places the jerk jumps; nothing below it jumps (exact by construction).
    jumps = cmd.jumps()
    assert np.all(jumps[:3] == 0.0)
    np.testing.assert_allclose(jumps[3], [40000.0, -40000.0, -40000.0, 40000.0], rtol=1e-14)


def test_rectangle_and_triangle_limits():
    rect = Stap(-2.0, 0.5, 0.0)  # Fig. 3 limit 1: t_j = 0, a = v/t_a
    assert rect.shape == "rectangle" and rect.jerk is None and rect.peak_acceleration == pytest.approx(-4.0)
    cmd = rect.command()
    assert cmd.time_s.tolist() == [0.0, 0.5]
    np.testing.assert_allclose(cmd.derivative(2), [-4.0, 0.0])
    assert cmd.continuous_orders == 2  # the acceleration jumps at both ends
    tri = Stap(3.0, 0.4, 0.2)  # Fig. 3 limit 2: t_j = t_a/2, peak 2 v/t_a
    assert tri.shape == "triangle" and tri.peak_acceleration == pytest.approx(15.0, rel=1e-15)
    assert tri.command().time_s.size == 3
    # Pieces shorter than 1e-9 s merge (a grid cannot hold them): into the rectangle and the triangle.
    assert Stap(1.0, 1.0, 1e-12).shape == "rectangle"
    assert Stap(1.0, 1.0, 0.5 - 1e-12).shape == "triangle"


@pytest.mark.parametrize(
    ("velocity", "t_a", "t_j", "field"),
    [
        (0.0, 1.0, 0.1, "velocity"),
        (1.0, -1.0, 0.1, "acceleration_time_s"),
        (1.0, 1.0, 0.6, "jerk_time_s"),
        (1.0, 1.0, -0.1, "jerk_time_s"),
    ],
)
def test_invalid_laws_name_the_field(velocity, t_a, t_j, field):
    with pytest.raises(InvalidParameter) as info:
        Stap(velocity, t_a, t_j)
    assert info.value.field == field


def test_section_3_residual_is_zero_on_the_resampled_samples():
    plant = ModePlant(40.0, 0.0)
    for stap in (SEC3, Stap(150.0, 0.2, 0.05), Stap(150.0, 0.225, 0.075)):  # k_j = 1, 2, 3 (Figs. 14-16)
        sampled = stap.command().resampled(1e-3, end_s=0.4)
        # The grid keeps the corners: the samples, acceleration held linearly, are the profile itself.
        again = PiecewiseCommand.from_samples(sampled.time_s, sampled.derivative(2), 2)
        np.testing.assert_allclose(again.derivative(1), sampled.derivative(1), rtol=0, atol=1e-11)
        m = metrics(simulate(plant, again))
        # Exact simulation: round-off only (the acceptance bound is 1e-9 of v_max).
        assert m.residual_velocity_amplitude <= 1e-9 * 150.0
        assert m.residual_amplitude <= 1e-9


def test_factorised_free_state_equals_the_simulation():
    # The free state (j/l^4)(exp(l (t_a - t_j)) - 1)(exp(l t_j) - 1) against the simulator's own
    # recurrence over the resampled command, for a damped mode and an off-design stap.
    plant = ModePlant(33.0, 0.07)
    stap = Stap(-80.0, 0.137, 0.041)
    response = simulate(plant, stap.command().resampled(7e-4, end_s=0.3))
    end = response.command.end_index()
    ours = stap.free_state(response.modal.poles)
    np.testing.assert_allclose(response.free_state[:, end], ours, rtol=1e-11)
    rect = Stap(5.0, 0.09, 0.0)
    response = simulate(plant, rect.command())
    np.testing.assert_allclose(response.free_state[:, -1], rect.free_state(response.modal.poles), rtol=1e-12)


@pytest.mark.parametrize("r_na", [2, 5, 10])
def test_appendix_b_equals_simulation(r_na):
    # Acceptance: (A5)-(A12) against the exact simulation of the STAP (k_j = 1) on undamped modes
    # at f_n = rho f_n,e; to 1e-9 of v_max (both are exact; round-off is ~1e-15).
    f_e = 8.0
    stap = Stap(150.0, r_na / f_e, 1.0 / f_e)
    ratios = np.concatenate([np.linspace(0.3, 2.0, 35), [1.0]])
    closed = sensitivity_appendix_b(ratios, float(r_na), 1.0)
    command = stap.command()
    simulated = (
        np.array([metrics(simulate(ModePlant(rho * f_e, 0.0), command)).residual_velocity_amplitude for rho in ratios])
        / 150.0
    )
    np.testing.assert_allclose(closed, simulated, rtol=0, atol=1e-9)
    assert closed[-1] <= 1e-15  # zero at the design frequency (eq. 44)
    assert np.max(closed) > 1e-3  # and not zero elsewhere: the comparison has teeth


def test_appendix_b_is_the_factorised_form_for_any_k_j():
    # PAPER-NOTES / lead: the residual factorises; A5-A12 equal 4 D |sin(pi rho k) sin(pi rho (r - k))|
    # also for non-integer k_j (side bands, optimised designs), and the ODE oracle agrees.
    rho = np.linspace(0.2, 3.0, 500)
    for r, k in [(6.6, 0.6), (7.0, 2.3), (2.0, 1.0), (9.5, 4.75)]:
        d = 1.0 / ((2 * np.pi) ** 2 * rho**2 * r * k * (1 - k / r))
        factorised = 4 * d * np.abs(np.sin(np.pi * rho * k) * np.sin(np.pi * rho * (r - k)))
        np.testing.assert_allclose(sensitivity_appendix_b(rho, r, k), factorised, rtol=1e-12, atol=1e-16)
    stap = Stap(1.0, 6.6 / 40, 0.6 / 40)
    plant = ModePlant(0.83 * 40, 0.0)
    command = stap.command().resampled(2e-3, end_s=0.3)
    ref = ivp_response(plant, command)
    # The load velocity minus the motor's (1) after t_a oscillates with the SC's amplitude.
    after = command.time_s > 0.166
    amplitude = np.max(np.abs(ref["velocity"][after] - 1.0))
    sc = float(sensitivity_appendix_b(np.array([0.83]), 6.6, 0.6)[0])
    assert amplitude <= sc * (1 + 1e-9)  # sampled peak of the oscillation never exceeds its envelope
    assert amplitude >= sc * np.cos(2 * np.pi * 0.83 * 40 * 2e-3 / 2)  # and a sample falls within half a step of it


def test_rectangle_sensitivity_is_the_limit_of_appendix_b():
    # A5-A12 cancel digits as k_j -> 0, so the limit is checked on the factorised form (no
    # cancellation: it differs from the limit by O(k_j)) and the rectangle against the simulator.
    rho = np.linspace(0.5, 1.5, 101)
    k, r = 1e-9, 6.0
    factorised = np.abs(np.sin(np.pi * rho * k) * np.sin(np.pi * rho * (r - k))) / (np.pi**2 * rho**2 * k * (r - k))
    np.testing.assert_allclose(rectangle_sensitivity(rho, r), factorised, rtol=0, atol=1e-8)
    rect = Stap(1.0, 0.15, 0.0)
    simulated = [
        metrics(simulate(ModePlant(x * 40.0, 0.0), rect.command())).residual_velocity_amplitude for x in rho[::10]
    ]
    np.testing.assert_allclose(stap_sensitivity(rect, 40.0, rho[::10]), simulated, rtol=0, atol=1e-12)


def test_zeros_of_the_exciting_term_eq_44():
    # Appendix A: u vanishes at t^_j = (k_j + delta dec(r))/r for delta = 0 and 1 (r = 6.7, Fig. 8).
    r = 6.7
    for k in range(4):
        for delta in (0, 1):
            if (k, delta) == (0, 0):
                continue
            t_hat = (k + delta * 0.7) / r
            assert abs(exciting_term_u(r, t_hat)) <= 1e-13
    assert abs(exciting_term_u(r, 0.2)) > 0.5  # not a zero: |u| is O(1) between zeros
    assert decimal_part(40 * 0.15) == 0.0  # 6.000000000000001 reads as a whole number of periods
    assert decimal_part(6.7) == pytest.approx(0.7, abs=1e-12)


def test_horizontal_tangent_only_for_whole_f_t_a():
    # PAPER-NOTES: the SC has a horizontal tangent at 1 only when f_n,e t_a is an integer.
    h = 1e-4
    slope_whole = (
        sensitivity_appendix_b(np.array([1 + h]), 7.0, 1.0) - sensitivity_appendix_b(np.array([1 - h]), 7.0, 1.0)
    ) / (2 * h)
    right = sensitivity_appendix_b(np.array([1 + h]), 6.6, 1.0)[0] / h  # simple zero: |SC| ~ c |rho - 1|
    assert abs(slope_whole[0]) < 1e-6
    assert right > 1e-3


def test_eq_57_values_and_against_the_simulated_load_acceleration():
    # Lead's check: eq. (57) at rho = 0.9, k_j = 1 is 0.1093, at 1.1 it is 0.0894.
    assert float(load_acceleration_oscillation(0.9, 1)) == pytest.approx(0.10929, abs=1e-5)
    assert float(load_acceleration_oscillation(1.1, 1)) == pytest.approx(0.08942, abs=1e-5)
    assert float(load_acceleration_oscillation(1.0, 1)) <= 1e-15
    # Independent: the load's free acceleration amplitude when the ramp reaches a_max (t = t_j) on
    # an undamped mode at 0.9 f_n,e, from the simulator's free state; exact, so 1e-12.
    f_e = 8.0
    stap = Stap(150.0, 0.15 + 1 / f_e, 1 / f_e)  # eq. 61 with a_Max = 1000
    response = simulate(ModePlant(0.9 * f_e, 0.0), stap.command())
    amplitude = response.free_amplitudes(1, derivative=2)[0]
    assert amplitude / stap.peak_acceleration == pytest.approx(float(load_acceleration_oscillation(0.9, 1)), rel=1e-12)


def test_eq_59_torque_overshoot_and_simulated_motor_torque():
    # Eq. (59) read with PAPER-NOTES: 0.5 * 0.1093 = 0.0546 for J_L = J_M (the paper's "about 0.055").
    assert float(motor_torque_oscillation(0.9, 1, 1.0)) == pytest.approx(0.05465, abs=1e-5)
    # Simulated: the Table 2 motor (J_M = J_L = 0.005) on a load at 0.9 * 8 Hz, STAP designed for 8 Hz
    # with a_max = 1000: the motor torque peaks at M_max (1 + 0.0546) during t_c (eq. 58: M_max = 10 N m).
    j = 0.005
    plant = TwoInertiaPlant(j, j, j * (2 * math.pi * 7.2) ** 2, 0.0)
    stap = Stap(150.0, 0.275, 0.125)
    assert motor_torque_scale(j, j, stap.peak_acceleration) == pytest.approx(10.0, rel=1e-12)
    torque = simulate(plant, stap.command().resampled(1e-5, end_s=0.275)).motor_torque_nm
    # Sampled at 1e-5 s: the sampled peak lies within (w h)^2/2 ~ 1e-7 of the oscillation's crest.
    assert float(np.max(torque)) == pytest.approx(10.0 * (1 + float(motor_torque_oscillation(0.9, 1, 1.0))), rel=1e-6)


def test_rest_to_rest_move():
    move = RestToRest(Stap(150.0, 0.175, 0.025), 0.025)
    assert move.displacement == pytest.approx(150.0 * 0.2)
    assert move.total_time_s == pytest.approx(0.375)
    cmd = move.command()
    np.testing.assert_allclose(cmd.time_s, [0, 0.025, 0.15, 0.175, 0.2, 0.225, 0.35, 0.375], atol=1e-15)
    assert cmd.derivative(0)[-1] == pytest.approx(30.0, rel=1e-15)
    assert cmd.derivative(1)[-1] == 0.0 and cmd.evaluate(1, np.array([1.0]))[0] == 0.0
    # Position continuity at every corner: the exact integrals agree with the Taylor steps.
    left = cmd.left_limits()
    np.testing.assert_allclose(left[0, 1:], cmd.derivative(0)[1:], rtol=1e-14)
    np.testing.assert_allclose(left[1, 1:], cmd.derivative(1)[1:], rtol=0, atol=1e-12)
    # No residual at the nominal frequency: each ramp leaves none (exact simulation).
    m = metrics(simulate(ModePlant(40.0, 0.0), cmd.resampled(1e-3, end_s=0.6)))
    assert m.residual_amplitude <= 1e-9 * 30.0
    # No cruise: the ramps meet.
    assert RestToRest(Stap(1.0, 0.5, 0.25), 0.0).command().time_s.size == 5
