"""A sampled drive (models.servo_sampled) against an independent simulation of the same machine.

The reference is written here from the physics: the controller's difference equations run sample by sample in a
Python loop, and between samples the motor, its current loop and the mechanics are integrated by scipy's DOP853
at rtol 1e-12 with the torque reference held. The model discretises the continuous part exactly (a matrix
exponential) and runs the loop in its eigenbasis, so the two agree to the integrator's tolerance: 1e-9 of each
output's range is 1000 times DOP853's rtol."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.metrics import metrics
from models.plants import ModePlant, TwoInertiaPlant
from models.servo import PI, Drive, Motor, current_pi, velocity_pi
from models.servo_response import simulate_drive

MOTOR = Motor(0.9, 0.015, 0.8, max_torque_nm=10.0)  # Cusimano Sec. 7's winding
SHAFT = TwoInertiaPlant(0.005, 0.005, 0.005 * (2 * math.pi * 8) ** 2, 0.0)  # Cusimano's 8 Hz shaft, J_L = J_M
SPRING = ModePlant(19.6895152, 0.1265341)  # Biagiotti Sec. VI's identified mode (PAPER-NOTES)


def jerk_command(duration_s: float = 0.6, step_s: float = 0.0005, jerk: float = 400.0) -> PiecewiseCommand:
    """Up to 20 rad/s^2 in 0.05 s, down, back to rest by 0.3 s, then at rest: a held jerk on a uniform grid."""
    t = np.arange(0.0, duration_s + step_s / 2, step_s)
    levels = np.select(
        [
            t < 0.05 - 1e-12,
            t < 0.1 - 1e-12,
            (t >= 0.2 - 1e-12) & (t < 0.25 - 1e-12),
            (t >= 0.25 - 1e-12) & (t < 0.3 - 1e-12),
        ],
        [jerk, -jerk, -jerk, jerk],
        0.0,
    )
    return PiecewiseCommand.from_held_steps(t, levels, 3)


def reference(mechanics: object, drive: Drive, command: PiecewiseCommand, samples: int) -> dict[str, np.ndarray]:
    """The sampled machine, sample by sample: state (th_M, w_M, load position, load velocity, i, int e_i)."""
    motor, period = drive.motor, drive.sample_period_s
    assert period is not None and drive.position_kp_per_s is not None
    two = isinstance(mechanics, TwoInertiaPlant)
    inertia = mechanics.motor_inertia_kgm2 + mechanics.load_inertia_kgm2 if two else motor.inertia_kgm2
    k_t = motor.torque_constant_nm_per_a

    def rates(_t: float, x: np.ndarray, torque_ref: float) -> list[float]:
        th, w, y, v, i, xi = x
        if drive.current is None:
            torque, di, dxi = torque_ref, 0.0, 0.0
        else:
            e_i = torque_ref / k_t - i
            voltage = drive.current.kp * e_i + drive.current.ki * xi
            torque, di, dxi = k_t * i, (voltage - motor.resistance_ohm * i - motor.k_e * w) / motor.inductance_h, e_i
        if two:
            twist = mechanics.stiffness_nm_per_rad * (th - y) + mechanics.damping_nms_per_rad * (w - v)
            return [w, (torque - twist) / mechanics.motor_inertia_kgm2, v, twist / mechanics.load_inertia_kgm2, di, dxi]
        w_n, zeta = 2 * math.pi * mechanics.natural_frequency_hz, mechanics.damping_ratio
        return [w, torque / inertia, v, w_n**2 * (th - y) + 2 * zeta * w_n * (w - v), di, dxi]

    t = command.time_s[0] + period * np.arange(samples)
    r = command.evaluate_at_instants(t, orders=3)
    x, integral, applied = np.zeros(6), 0.0, 0.0
    out: dict[str, list[float]] = {"motor": [], "load": [], "torque": []}
    for k in range(samples):  # the controller runs once a sample
        out["motor"].append(x[0])
        out["load"].append(x[2])
        out["torque"].append(applied if drive.current is None else k_t * x[4])
        e_v = drive.position_kp_per_s * (r[0, k] - x[0]) + r[1, k] - x[1]
        integral += period * e_v
        computed = drive.velocity.kp * e_v + drive.velocity.ki * integral + inertia * r[2, k]
        if k + 1 < samples:
            x = solve_ivp(rates, (0.0, period), x, args=(applied,), method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
        applied = computed  # one sample of computation delay, then held
    return {name: np.array(values) for name, values in out.items()}


CASES = [
    pytest.param(
        SHAFT,
        Drive(2 * math.pi * 2, velocity_pi(20, 0.01), current_pi(800, MOTOR), MOTOR, sample_period_s=1e-3),
        id="shaft-current-loop",
    ),
    pytest.param(
        SPRING,
        Drive(
            2 * math.pi * 8, velocity_pi(40, 0.5), None, Motor(1.0, 1e-3, 10.0, inertia_kgm2=0.5), sample_period_s=5e-4
        ),
        id="linear-motor-ideal-current",
    ),
]


@pytest.mark.parametrize(("mechanics", "drive"), CASES)
def test_the_sampled_loop_is_the_machine_at_its_samples(mechanics, drive):
    command = jerk_command(step_s=0.00075)  # breakpoints between the samples: the controller samples the command
    run = simulate_drive(mechanics, drive, command)
    expected = reference(mechanics, drive, command, run.time_s.size)
    assert run.time_s[1] - run.time_s[0] == pytest.approx(drive.sample_period_s, rel=1e-12)
    for name, got in (("motor", run.motor_position), ("load", run.load.load_position), ("torque", run.torque_nm)):
        scale = float(np.ptp(expected[name]))
        assert np.max(np.abs(got - expected[name])) <= 1e-9 * scale, name


def test_the_free_response_after_the_end_is_the_loops_modes():
    """What metrics measure after the command's end (the equivalent poles ln(mu) / T_s and the free state there)
    is what the loop does: the same command with 2 s more of rest, simulated sample by sample, agrees with
    g_0 p + Re sum w r h_end exp(s (t - t_end)) to 1e-10 of the move."""
    drive = Drive(2 * math.pi * 2, velocity_pi(20, 0.01), current_pi(800, MOTOR), MOTOR, sample_period_s=1e-3)
    short = simulate_drive(SHAFT, drive, jerk_command())
    longer = simulate_drive(SHAFT, drive, jerk_command(duration_s=2.6))
    load = short.load
    end = load.command.end_index()
    assert load.time_s[end] == pytest.approx(0.3, abs=1e-12)
    modal, h = load.modal, load.free_state[:, end]
    later = longer.time_s[longer.time_s >= load.time_s[end] - 1e-12]
    tau = later - load.time_s[end]
    free = np.real(np.sum((modal.weights * modal.residues * h)[:, None] * np.exp(np.outer(modal.poles, tau)), axis=0))
    predicted = modal.taylor[0] * load.command.derivatives[0, end] + free
    actual = longer.load.load_position[-later.size :]
    assert np.max(np.abs(actual - predicted)) <= 1e-10 * 0.2
    assert np.max(np.abs(free)) > 1e-4  # (the loop rings: the comparison is not of zeros)


def test_a_finer_sample_period_tends_to_the_continuous_loop():
    """The sampled loop lags the continuous one by a sample and a half (the computation delay and the hold): its
    difference from the continuous prediction is first order in T_s, ten times smaller at a ten times shorter
    period (within 30 %: the next order), and the residual tends to the continuous one."""
    continuous = Drive(2 * math.pi * 2, velocity_pi(20, 0.01), current_pi(800, MOTOR), MOTOR)
    command = jerk_command(step_s=0.0005)
    exact = simulate_drive(SHAFT, continuous, command)
    gaps, residuals = [], []
    for period in (1e-3, 1e-4):
        sampled = Drive(
            *[getattr(continuous, f) for f in ("position_kp_per_s", "velocity", "current", "motor")],
            sample_period_s=period,
        )
        run = simulate_drive(SHAFT, sampled, command)
        at = np.minimum(np.searchsorted(command.time_s, run.time_s - 1e-12), command.time_s.size - 1)
        inside = np.abs(command.time_s[at] - run.time_s) <= 1e-12  # the instants both give
        gaps.append(float(np.max(np.abs(run.load.load_position[inside] - exact.load.load_position[at[inside]]))))
        residuals.append(metrics(run.load).residual_amplitude)
    assert 7.0 <= gaps[0] / gaps[1] <= 13.0, gaps
    reference_residual = metrics(exact.load).residual_amplitude
    assert abs(residuals[1] - reference_residual) <= 0.2 * abs(residuals[0] - reference_residual) + 1e-12


def test_an_unstable_sampled_loop_and_a_velocity_mode_one_are_refused():
    """Gains stable in continuous time, unstable with a 5 ms sample and its delay: named, with |z|; a sampled
    drive needs its position loop."""
    gains = (2 * math.pi * 5, velocity_pi(60, 0.5), None, Motor(1.0, 1e-3, 10.0, inertia_kgm2=0.5))
    simulate_drive(SPRING, Drive(*gains), jerk_command())  # stable when continuous
    with pytest.raises(InvalidParameter) as refused:
        simulate_drive(SPRING, Drive(*gains, sample_period_s=5e-3), jerk_command())
    assert refused.value.field == "drive" and "sampled" in refused.value.rule and "|z|" in refused.value.rule
    velocity_mode = Drive(None, PI(0.3, 20.0), None, Motor(0.9, 0.015, 0.8, inertia_kgm2=0.004), sample_period_s=1e-3)
    with pytest.raises(InvalidParameter) as refused:
        simulate_drive(SPRING, velocity_mode, jerk_command())
    assert refused.value.field == "drive.position_loop"


def test_a_mode_above_the_nyquist_frequency_is_refused():
    """A 900 Hz mode sampled every 1 ms (Nyquist 500 Hz) would alias to 100 Hz at the samples: refused, named."""
    motor = Motor(1.0, 1e-3, 10.0, inertia_kgm2=0.5)
    drive = Drive(2 * math.pi * 8, velocity_pi(40, 0.5), None, motor, sample_period_s=1e-3)
    with pytest.raises(InvalidParameter) as refused:
        simulate_drive(ModePlant(900.0, 0.01), drive, jerk_command())
    assert refused.value.field == "drive.sample_period_s" and "Nyquist" in refused.value.rule
    simulate_drive(ModePlant(400.0, 0.01), drive, jerk_command())  # below it: answered
