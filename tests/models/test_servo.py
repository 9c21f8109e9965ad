"""The drive in the loop (models.servo, models.servo_response) against an independent integration of its equations.

The reference is written here from the physics, in its own state order, and integrated by scipy's DOP853 at
rtol 1e-12 segment by segment between the command's jerk steps (where its right-hand side is smooth): the
model's partial fractions are exact, so the two agree to the integrator's tolerance (1e-9 of each output's
range is 1000 times the integrator's rtol, and 1e-6 of the time steps' round-off)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.plants import ModePlant, TwoInertiaPlant, example_plants
from models.servo import PI, Drive, Motor, closed_loop, current_pi, velocity_pi
from models.servo_response import load_plant, simulate_drive
from models.simulation import simulate

CUSIMANO_MOTOR = Motor(0.9, 0.015, 0.8, max_torque_nm=10.0)  # Cusimano Sec. 7: R, L, K_T = K_E, torque limit


def jerk_command(samples: int = 801, duration_s: float = 0.6, jerk: float = 400.0) -> PiecewiseCommand:
    """Up to 20 rad/s^2 in 0.05 s, down, and back to rest by 0.3 s: a held jerk on a uniform grid."""
    t = np.linspace(0.0, duration_s, samples)
    levels = np.select(
        [t < 0.05, t < 0.1, (t >= 0.2) & (t < 0.25), (t >= 0.25) & (t < 0.3)], [jerk, -jerk, -jerk, jerk], 0.0
    )
    return PiecewiseCommand.from_held_steps(t, levels, 3)


def reference(mechanics: object, drive: Drive, command: PiecewiseCommand) -> dict[str, np.ndarray]:
    """The same machine integrated from its equations: state (r, r', r'', th_M, w_M, load..., int e_v, i, int e_i)."""
    motor = drive.motor
    two = isinstance(mechanics, TwoInertiaPlant)
    if two:
        j_m, j_l = mechanics.motor_inertia_kgm2, mechanics.load_inertia_kgm2
        inertia = j_m + j_l
    else:
        assert isinstance(mechanics, ModePlant) and motor.inertia_kgm2 is not None
        inertia = motor.inertia_kgm2
        w_n = 2 * math.pi * mechanics.natural_frequency_hz
        zeta = mechanics.damping_ratio

    def signals(x: np.ndarray) -> dict[str, float]:
        r, v, a, th, w, l1, l2, xv, i, xi = x
        w_ref = (drive.position_kp_per_s or 0.0) * (r - th) + v  # None: a velocity-mode drive
        e_v = w_ref - w
        t_ref = drive.velocity.kp * e_v + drive.velocity.ki * xv + inertia * a
        if drive.current is None:
            current, volt_rate, i_rate = t_ref / motor.torque_constant_nm_per_a, 0.0, 0.0
        else:
            e_i = t_ref / motor.torque_constant_nm_per_a - i
            voltage = drive.current.kp * e_i + drive.current.ki * xi
            current, volt_rate = i, e_i
            i_rate = (voltage - motor.resistance_ohm * i - motor.k_e * w) / motor.inductance_h
        torque = motor.torque_constant_nm_per_a * current
        if two:
            twist = mechanics.stiffness_nm_per_rad * (th - l1) + mechanics.damping_nms_per_rad * (w - l2)
            accel, load_rates = (torque - twist) / j_m, (l2, twist / j_l)
        else:  # the load y'' = w_n^2 (th - y) + 2 zeta w_n (w - y') follows the motor
            accel = torque / inertia
            load_rates = (l2, w_n**2 * (th - l1) + 2 * zeta * w_n * (w - l2))
        return {"rates": (w, accel, *load_rates, e_v, i_rate, volt_rate), "torque": torque, "current": current}

    out: dict[str, list[float]] = {"motor": [], "load": [], "torque": [], "current": []}
    t, levels = command.time_s, command.derivatives[3]
    x = np.zeros(10)

    def record(x: np.ndarray) -> None:
        s = signals(x)
        out["motor"].append(x[3])
        out["load"].append(x[5])
        out["torque"].append(s["torque"])
        out["current"].append(s["current"])

    record(x)
    for k in range(t.size - 1):  # a test's reference: a loop over steps is its point
        jerk = levels[k]

        def rhs(_t: float, y: np.ndarray, jerk: float = jerk) -> np.ndarray:
            return np.array([y[1], y[2], jerk, *signals(y)["rates"]])

        x = solve_ivp(rhs, (t[k], t[k + 1]), x, method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
        record(x)
    return {name: np.array(values) for name, values in out.items()}


def _close(model: np.ndarray, ref: np.ndarray, relative: float) -> None:
    scale = float(np.max(np.abs(ref)))
    assert float(np.max(np.abs(model - ref))) <= relative * scale, float(np.max(np.abs(model - ref))) / scale


CASES = {
    "cusimano two_inertia, current PI": (
        example_plants()["cusimano_8hz_equal_inertia"],
        Drive(2 * math.pi * 2, velocity_pi(20, 0.01), current_pi(800, CUSIMANO_MOTOR), CUSIMANO_MOTOR),
    ),
    "damped two_inertia, ideal current": (
        TwoInertiaPlant(0.005, 0.00125, 0.00125 * (2 * math.pi * 8) ** 2, 0.004),
        Drive(2 * math.pi * 5, velocity_pi(30, 0.00625), None, CUSIMANO_MOTOR),
    ),
    "cusimano two_inertia, velocity mode (Fig. 20)": (
        example_plants()["cusimano_8hz_equal_inertia"],
        Drive(None, velocity_pi(20, 0.01), current_pi(800, CUSIMANO_MOTOR), CUSIMANO_MOTOR),
    ),
    "mode, velocity mode": (
        ModePlant(12.0, 0.05),
        Drive(None, PI(0.3, 20.0), None, Motor(0.9, 0.015, 0.8, inertia_kgm2=0.004)),
    ),
    "mode, motor inertia": (
        ModePlant(12.0, 0.05),
        Drive(
            2 * math.pi * 10, PI(0.3, 20.0), current_pi(500, CUSIMANO_MOTOR), Motor(0.9, 0.015, 0.8, inertia_kgm2=0.004)
        ),
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_the_closed_loop_is_the_integrated_equations(name: str) -> None:
    mechanics, drive = CASES[name]
    command = jerk_command()
    model = simulate_drive(mechanics, drive, command)
    ref = reference(mechanics, drive, command)
    _close(model.motor_position, ref["motor"], 1e-9)
    _close(model.load.load_position, ref["load"], 1e-9)
    _close(model.torque_nm, ref["torque"], 1e-9)
    _close(model.current_a, ref["current"], 1e-9)


def test_stiff_loops_give_the_ideal_motor() -> None:
    """With the torque ideal and both feed-forwards, a rigid motor tracks exactly (its error starts at zero and
    obeys a homogeneous equation): the load is the ideal motor's to round-off; with a current loop 1000 times
    faster than the mode the difference stays below 1e-6 of the move."""
    plant = ModePlant(10.0, 0.02)
    motor = Motor(0.9, 0.015, 0.8, inertia_kgm2=0.004)
    command = jerk_command()
    ideal = simulate(plant, command).load_position
    exact = simulate_drive(plant, Drive(2 * math.pi * 100, velocity_pi(500, 0.004), None, motor), command)
    _close(exact.load.load_position, ideal, 1e-9)
    stiff = Drive(2 * math.pi * 200, velocity_pi(1000, 0.004), current_pi(10_000, motor), motor)
    _close(simulate_drive(plant, stiff, command).load.load_position, ideal, 1e-6)


def test_an_unstable_loop_is_refused_with_its_gains_and_poles() -> None:
    """An 80 Hz velocity loop on Cusimano's undamped 8 Hz shaft (J_L = J_M) destabilises the anti-resonance."""
    plant = example_plants()["cusimano_8hz_equal_inertia"]
    drive = Drive(2 * math.pi * 15, velocity_pi(80, 0.01), current_pi(800, CUSIMANO_MOTOR), CUSIMANO_MOTOR)
    with pytest.raises(InvalidParameter) as caught:
        closed_loop(plant, drive)
    assert caught.value.field == "drive"
    assert "unstable" in caught.value.rule and "velocity kp" in str(caught.value.value)
    assert "Hz" in caught.value.rule


def test_a_torque_beyond_the_limit_is_reported() -> None:
    motor = Motor(0.9, 0.015, 0.8, max_torque_nm=0.1)
    plant = example_plants()["cusimano_8hz_equal_inertia"]
    response = simulate_drive(plant, Drive(2 * math.pi * 2, velocity_pi(20, 0.01), None, motor), jerk_command())
    assert response.saturated
    (saturation,) = response.saturation
    assert saturation.quantity == "torque_nm" and saturation.peak > 0.1
    assert saturation.peak == pytest.approx(float(np.max(np.abs(response.torque_nm))))


def test_a_velocity_input_plant_through_the_drive_is_simulated() -> None:
    """Chatlatanagulchai's eq. (3) plant (its command the drive's velocity) behind a motor: the load's closed-loop
    poles are too clustered for partial fractions of its polynomial, which a transfer_function plant refuses; the
    simulation takes them from the eigenvectors, so it runs, and its modes are the loop's."""
    plant = example_plants()["chatlatanagulchai_eq3"]
    motor = Motor(0.9, 0.015, 0.8, inertia_kgm2=2.0)
    drive = Drive(2 * math.pi * 2, velocity_pi(20, 2.0), current_pi(800, motor), motor)
    response = simulate_drive(plant, drive, jerk_command())
    loop = closed_loop(plant, drive)
    assert response.modes == loop.modes() and all(m.damping_ratio < 1 for m in response.modes)
    assert np.all(np.isfinite(response.load.load_position))


@pytest.mark.parametrize("name", ["cusimano two_inertia, current PI", "cusimano two_inertia, velocity mode (Fig. 20)"])
def test_the_closed_loop_plant_is_the_simulated_closed_loop(name: str) -> None:
    """What a family designs for (the closed_loop plant: the load's transfer function as polynomials, simulated as
    any plant from their roots) is what the drive does (partial fractions from the eigenvectors): the same load to
    1e-12 of its motion (3e-15 measured; the poles span 2 or 7.6 Hz to 760 Hz: the roots of a degree-7 polynomial
    lose little here, which the eigenvectors guard against for wider spans)."""
    mechanics, drive = CASES[name]
    command = jerk_command()
    through = simulate_drive(mechanics, drive, command).load.load_position
    designed_for = simulate(load_plant(closed_loop(mechanics, drive)), command).load_position
    _close(designed_for, through, 1e-12)
