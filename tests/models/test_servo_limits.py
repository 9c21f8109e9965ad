"""A drive at its limits (models.servo_limits) against the equations integrated independently.

The reference is written here from the physics with the drive's limits as a drive applies them: the current
reference clamped to +-max_torque_nm / K_T, the current PI's output to +-max_voltage_v, each PI's integrator fed
back (u_sat - u) / kp (back-calculation, T_t = kp / ki; Astrom & Hagglund 2006, Sec. 3.5). It is integrated in its
own state order by scipy's DOP853 at rtol 1e-12, segment by segment between the command's jerk steps. The model
integrates with LSODA at rtol 1e-10 across the clamps' corners, so they agree to 1e-7 of each output's range
(1000 times the model's rtol; 1e-9 relative measured where no limit is reached, 1e-8 where one is)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from models.commands import PiecewiseCommand
from models.metrics import metrics
from models.plants import ModePlant, TwoInertiaPlant, example_plants
from models.servo import PI, Drive, Motor, current_pi, velocity_pi
from models.servo_response import simulate_drive
from tests.models.test_servo_sampled import jerk_command

SHAFT = example_plants()["cusimano_8hz_equal_inertia"]


def motor(max_torque_nm: float = math.inf, max_voltage_v: float = math.inf) -> Motor:
    return Motor(0.9, 0.015, 0.8, max_torque_nm=max_torque_nm, max_voltage_v=max_voltage_v)


def cascade(limits: Motor, position: bool = True) -> Drive:
    """Cusimano's shaft under a soft cascade: position 2 Hz (or none), velocity 20 Hz, current 800 Hz."""
    return Drive(2 * math.pi * 2 if position else None, velocity_pi(20, 0.01), current_pi(800, limits), limits)


def reference(mechanics: object, drive: Drive, command: PiecewiseCommand) -> dict[str, np.ndarray]:
    """State (r, r', r'', th_M, w_M, load position, load velocity, int e_v, i, int e_i)."""
    m = drive.motor
    two = isinstance(mechanics, TwoInertiaPlant)
    inertia = mechanics.motor_inertia_kgm2 + mechanics.load_inertia_kgm2 if two else m.inertia_kgm2
    k_t, i_max = m.torque_constant_nm_per_a, m.max_torque_nm / m.torque_constant_nm_per_a
    kp_p = drive.position_kp_per_s or 0.0  # a velocity-mode drive: no position feedback

    def signals(y: np.ndarray) -> dict[str, object]:
        r, v, a, th, w, l1, l2, xv, i, xi = y
        e_v = kp_p * (r - th) + v - w
        i_ref = (drive.velocity.kp * e_v + drive.velocity.ki * xv + inertia * a) / k_t
        i_sat = min(max(i_ref, -i_max), i_max)
        xv_rate = e_v + k_t * (i_sat - i_ref) / drive.velocity.kp
        if drive.current is None:
            torque, i_rate, xi_rate = k_t * i_sat, 0.0, 0.0
        else:
            e_i = i_sat - i
            demand = drive.current.kp * e_i + drive.current.ki * xi
            voltage = min(max(demand, -m.max_voltage_v), m.max_voltage_v)
            torque, xi_rate = k_t * i, e_i + (voltage - demand) / drive.current.kp
            i_rate = (voltage - m.resistance_ohm * i - m.k_e * w) / m.inductance_h
        if two:
            twist = mechanics.stiffness_nm_per_rad * (th - l1) + mechanics.damping_nms_per_rad * (w - l2)
            accel, load = (torque - twist) / mechanics.motor_inertia_kgm2, (l2, twist / mechanics.load_inertia_kgm2)
        else:
            w_n, zeta = 2 * math.pi * mechanics.natural_frequency_hz, mechanics.damping_ratio
            accel, load = torque / inertia, (l2, w_n**2 * (th - l1) + 2 * zeta * w_n * (w - l2))
        return {"rates": (w, accel, *load, xv_rate, i_rate, xi_rate), "torque": torque}

    t, levels = command.time_s, command.derivatives[3]
    x = np.zeros(10)
    x[0] = command.derivatives[0, 0]
    x[3] = x[5] = command.derivatives[0, 0]
    out: dict[str, list[float]] = {"motor": [x[3]], "load": [x[5]], "torque": [0.0]}
    for k in range(t.size - 1):  # a test's reference: a loop over steps is its point
        jerk = levels[k]

        def rhs(_t: float, y: np.ndarray, jerk: float = jerk) -> np.ndarray:
            return np.array([y[1], y[2], jerk, *signals(y)["rates"]])

        x = solve_ivp(rhs, (t[k], t[k + 1]), x, method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
        s = signals(x)
        for name, value in (("motor", x[3]), ("load", x[5]), ("torque", s["torque"])):
            out[name].append(value)
    return {name: np.array(values) for name, values in out.items()}


CASES = {
    "shaft, torque limit": (SHAFT, cascade(motor(max_torque_nm=0.1))),
    "shaft, voltage limit": (SHAFT, cascade(motor(max_voltage_v=0.5))),
    "shaft, velocity mode, torque limit": (SHAFT, cascade(motor(max_torque_nm=0.15), position=False)),
    "mode, ideal current, force limit": (
        ModePlant(12.0, 0.05),
        Drive(2 * math.pi * 10, PI(0.3, 20.0), None, Motor(0.9, 0.015, 0.8, max_torque_nm=0.05, inertia_kgm2=0.004)),
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_at_its_limits_the_drive_is_the_equations_integrated(name: str) -> None:
    mechanics, drive = CASES[name]
    command = jerk_command(duration_s=1.2)  # 0.9 s at rest after the move: the drive leaves its limits before
    run = simulate_drive(mechanics, drive, command)
    ref = reference(mechanics, drive, command)
    assert run.simulation == "limited" and run.saturated and run.note is None
    size = command.time_s.size
    assert run.time_s.size == size  # (back within its limits before the command's last sample)
    for got, expected in (
        (run.motor_position, ref["motor"]),
        (run.load.load_position, ref["load"]),
        (run.torque_nm, ref["torque"]),
    ):
        assert np.max(np.abs(got - expected)) <= 1e-7 * np.ptp(expected)
    (limit,) = run.saturation  # reported with what an unlimited drive would need
    free = dataclasses.replace(drive.motor, max_torque_nm=math.inf, max_voltage_v=math.inf)
    unlimited = simulate_drive(mechanics, dataclasses.replace(drive, motor=free), command)
    needed = unlimited.torque_nm if limit.quantity == "torque_nm" else unlimited.voltage_v
    assert limit.peak == float(np.max(np.abs(needed))) and limit.peak > limit.limit
    if limit.quantity == "torque_nm":  # the current loop follows the clamped reference
        assert np.max(np.abs(run.torque_nm)) <= limit.limit * (1 + 1e-3)


def test_within_its_limits_the_limited_simulation_is_the_linear_one() -> None:
    """The limited simulation where no limit is reached (forced, by calling it on the linear run's machine) against
    the exact linear one: the integrator's tolerance, and the same free state at the command's end."""
    from models.servo_limits import simulate_limited
    from models.servo_response import prepared

    drive = cascade(motor())
    command = jerk_command(step_s=0.0005)
    linear = simulate_drive(SHAFT, drive, command)
    machine = prepared(SHAFT, drive)
    run = simulate_limited(SHAFT, drive, command, machine.loop, linear.load.modal, machine.load_plant)
    end = command.end_index()
    assert run.free_from == end
    assert np.max(np.abs(run.load.load_position - linear.load.load_position)) <= 1e-8 * 0.2
    assert np.max(np.abs(run.load.load_velocity - linear.load.load_velocity)) <= 1e-8 * np.ptp(
        linear.load.load_velocity
    )
    amplitudes, exact = run.load.free_amplitudes(end), linear.load.free_amplitudes(end)
    assert np.sort(amplitudes) == pytest.approx(np.sort(exact), rel=1e-6, abs=1e-12)
    assert metrics(run.load).settling.time_s == pytest.approx(metrics(linear.load).settling.time_s, rel=1e-6)


def test_a_drive_still_at_its_limit_after_the_end_is_followed_until_it_cannot_reach_it_again() -> None:
    """A 0.1 N m motor behind the soft cascade still needs its limit after the command's end: the simulation runs
    on, and from ``free_from`` on, the load is the linear loop's free response from that state (the same command
    followed by 2 s at rest, against the modal prediction, to the integrator's tolerance), and the demand stays
    within the limit."""
    drive = cascade(motor(max_torque_nm=0.1))
    run = simulate_drive(SHAFT, drive, jerk_command(step_s=0.0005))
    end = run.load.command.end_index()
    assert run.free_from is not None and run.free_from > end
    longer = simulate_drive(SHAFT, drive, jerk_command(duration_s=2.6, step_s=0.0005))
    start = run.free_from
    tau = longer.time_s[start:] - run.time_s[start]
    modal, h = run.load.modal, run.load.free_state[:, start]
    free = np.real(np.sum((modal.weights * modal.residues * h)[:, None] * np.exp(np.outer(modal.poles, tau)), axis=0))
    predicted = modal.taylor[0] * run.load.command.derivatives[0, start] + free
    assert np.max(np.abs(longer.load.load_position[start:] - predicted)) <= 1e-7 * 0.2
    assert np.max(np.abs(free)) > 1e-4  # (it rings: not a comparison of zeros)
    (limit,) = longer.saturation
    assert np.all(np.abs(longer.torque_nm[start:]) <= limit.limit)
    settle = metrics(run.load, free_from=run.free_from).settling.time_s
    assert settle is not None and settle > run.time_s[start] - run.time_s[0]


def test_a_velocity_mode_drive_at_its_limit_loses_position_and_the_metrics_say_so() -> None:
    """Without a position loop nothing brings back the position a torque limit cost: the load ends off target (by
    7.2 mrad here, 34 times the 0.21 mrad band of a 0.2 rad move) and never settles there, though its vibration
    dies out. The metrics carry that offset (a pole at s = 0) rather than measuring the free vibration alone."""
    drive = cascade(motor(max_torque_nm=0.15), position=False)
    run = simulate_drive(SHAFT, drive, jerk_command(duration_s=4.0))
    target = float(run.load.command.derivatives[0, -1])
    offset = abs(float(run.load.load_position[-1]) - target)
    measured = metrics(run.load, free_from=run.free_from)
    assert offset > 10 * measured.settling.window
    assert measured.settling.time_s is None
    # the free response from free_from with that offset is what the drive does: at the last sample, 3.5 s later
    load, start = run.load, run.free_from
    modal, h = load.modal, load.free_state[:, start]
    tau = float(load.time_s[-1] - load.time_s[start])
    free = np.real(np.sum(modal.weights * modal.residues * h * np.exp(modal.poles * tau)))
    predicted = modal.taylor[0] * target + free
    assert abs(float(load.load_position[-1]) - predicted) <= 1e-7 * 0.2
    assert float(modal.residues[-1].real) == pytest.approx(float(load.load_position[-1]) - target, abs=2e-6)


def test_a_move_a_thousand_times_smaller_against_limits_a_thousand_times_lower_is_the_same_motion_scaled() -> None:
    """The loop is linear between its limits, so scaling the move and the limits together scales the motion: the
    integrator's tolerances follow the move (an absolute tolerance would not), to the same 1e-7."""
    big = simulate_drive(SHAFT, cascade(motor(max_torque_nm=0.1)), jerk_command())
    small_command = jerk_command(jerk=0.4)
    small = simulate_drive(SHAFT, cascade(motor(max_torque_nm=1e-4)), small_command)
    assert big.simulation == small.simulation == "limited"
    scaled = 1e3 * small.load.load_position
    assert np.max(np.abs(scaled - big.load.load_position)) <= 1e-7 * np.ptp(big.load.load_position)
