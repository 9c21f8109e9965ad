"""Cusimano Sec. 7 through the drive: the STAP of Table 2's motor in a closed velocity chain with an inner current
chain (Fig. 20), J_L = J_M, f_n,e = 8 Hz, the true shaft at f_n,e and at 0.9 f_n,e.

The paper does not give the controller's gains. Chosen here, by the named rules (app.schemas.drive): no position
loop (Fig. 20 closes velocity and current only), a 100 Hz velocity loop (symmetric optimum, J = J_M + J_L) and a
2.5 kHz current loop (internal model control): the stiffest pair for which the closed loop's load mode sits within
0.4 % of the shaft's 8 Hz (at 20 Hz it is 7.59 Hz, and the STAP designed for 8 Hz then rings through the drive at
f_n = f_n,e: the soft loop that the closed_loop plant kind designs through, tests/app/test_drive_api.py)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.app.test_stap_api import PATH, two_inertia

DRIVE = {
    "position_loop": None,
    "velocity_loop": {"bandwidth_hz": 100.0},
    "current_loop": {"bandwidth_hz": 2500.0},
    "motor": {"resistance_ohm": 0.9, "inductance_h": 0.015, "torque_constant_nm_per_a": 0.8, "max_torque_nm": 10.0},
}
LIMIT_NM = 10.0


@pytest.fixture(scope="module")
def stap(client):
    """Table 2's STAP for J_L = J_M (its acceleration limit lowered to 0.948 of the nodal one, eq. 59)."""
    request = {
        "plant": two_inertia(0.005),
        "target_velocity": 150.0,
        "max_torque_nm": LIMIT_NM,
        "jerk_periods": 1,
        "sensitivity": {"min_ratio": 0.8, "max_ratio": 1.2, "count": 41},
    }
    answer = client.post(PATH, json=request)
    assert answer.status_code == 200, answer.text
    return answer.json()


def _through_drive(client, stap: dict, frequency_hz: float) -> dict:
    """The design's samples (its acceleration, exact between them) through the drive on the true shaft."""
    profile = stap["profile"]
    body = {
        "plant": two_inertia(0.005, frequency_hz),
        "profile": {
            "time_s": profile["time_s"],
            "velocity": profile["velocity"],
            "acceleration": profile["acceleration"],
        },
        "held_quantity": "acceleration",
        "drive": DRIVE,
    }
    answer = client.post("/v1/simulate", json=body)
    assert answer.status_code == 200, answer.text
    return answer.json()["closed_loop"]


def test_the_motor_follows_the_stap_closely(client, stap):
    """Fig. 21's claim: the motor's acceleration is the STAP's within 0.5 % of its peak (0.48 % measured: the
    velocity loop's lag over the 7.5 ms jerk ramps)."""
    closed = _through_drive(client, stap, 8.0)
    commanded = np.array(stap["profile"]["acceleration"])
    motor = np.array(closed["motor"]["acceleration"])
    assert np.max(np.abs(motor - commanded)) <= 0.005 * np.max(np.abs(commanded))


def test_the_residual_at_f_ne_is_10x_below_the_one_at_0_9_f_ne_which_the_sensitivity_curve_predicts(client, stap):
    """Extremely small at f_n = f_n,e, "small but tangible" at 0.9 f_n,e (measured 0.087 and 1.938 rad/s); the
    latter is the ideal motor's sensitivity curve's value at 0.9 (1.938 rad/s) within a factor 2 (the drive hardly
    changes a residual it did not cause)."""
    at_design = _through_drive(client, stap, 8.0)["metrics"]["residual_velocity_amplitude"]
    detuned = _through_drive(client, stap, 7.2)["metrics"]["residual_velocity_amplitude"]
    assert detuned >= 10 * at_design
    curve = stap["sensitivity"]
    ratios = np.array(curve["frequency_ratio"])
    predicted = curve["residual_amplitude"][int(np.argmin(np.abs(ratios - 0.9)))]
    assert predicted / 2 <= detuned <= 2 * predicted


def test_the_torque_oscillates_by_about_0_055_of_its_limit_and_a_crossing_is_reported(client, stap):
    """At 0.9 f_n,e the motor torque oscillates while the speed is held (Figs. 18-19: |M_m,c| ~ 0.055 M_Max;
    measured 0.044 here, where the lowered limit scales it by 0.948 and the velocity loop damps the load mode). The
    lowered acceleration limit (eq. 59: 0.948) keeps the torque the loop asks for within 0.2 % of the limit
    (10.010 N m): the crossing is reported, and the answer is the drive at its limit (its current reference
    clamped)."""
    closed = _through_drive(client, stap, 7.2)
    torque = np.array(closed["motor"]["torque_nm"])
    held = np.array(stap["profile"]["time_s"]) > stap["design"]["acceleration_time_s"] + 0.01
    assert 0.03 * LIMIT_NM <= np.max(np.abs(torque[held])) <= 0.06 * LIMIT_NM
    peak = float(np.max(np.abs(torque)))
    assert LIMIT_NM * 0.99 <= peak <= LIMIT_NM  # the motor gives what the drive allows
    assert closed["saturated"] and closed["simulation"] == "limited"
    (crossing,) = closed["saturation"]
    assert crossing["quantity"] == "torque_nm" and LIMIT_NM < crossing["peak"] <= LIMIT_NM * 1.002


@pytest.mark.parametrize("frequency_hz", [7.2, 8.0, 8.8])
def test_the_papers_lowered_limit_keeps_the_torque_within_it_through_the_drive(client, frequency_hz):
    """Sec. 7: the acceleration limit 'must be lowered to 0.94' of the nodal one, M / (J_M + J_L) = 1000 rad/s^2.
    eq. 59's 0.948 leaves the loop asking 10.008 N m at 0.9 f_n,e (above); 0.94 keeps it within 10 N m through
    the drive at 0.9, 1.0 and 1.1 f_n,e (9.92, 9.41 and 9.64 N m measured): no saturation, a linear answer."""
    request = {"plant": two_inertia(0.005), "target_velocity": 150.0, "max_acceleration": 940.0, "jerk_periods": 1}
    answer = client.post(PATH, json=request)
    assert answer.status_code == 200, answer.text
    closed = _through_drive(client, answer.json(), frequency_hz)
    assert closed["saturated"] is False and closed["simulation"] == "linear"
    assert 0.9 * LIMIT_NM <= max(abs(x) for x in closed["motor"]["torque_nm"]) <= LIMIT_NM
