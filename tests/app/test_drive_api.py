"""The drive in the loop over HTTP: ``drive`` on /v1/simulate and the ``closed_loop`` plant kind (issue 26)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from models.commands import PiecewiseCommand
from models.plants import example_plants
from models.servo import Drive, Motor, current_pi, velocity_pi
from models.servo_response import simulate_drive

CUSIMANO = {
    "kind": "two_inertia",
    "motor_inertia_kgm2": 0.005,
    "load_inertia_kgm2": 0.005,
    "stiffness_nm_per_rad": 0.005 * (2 * math.pi * 8) ** 2,
}
MOTOR = {"resistance_ohm": 0.9, "inductance_h": 0.015, "torque_constant_nm_per_a": 0.8, "max_torque_nm": 10.0}
# A soft velocity loop (20 Hz on the 8 Hz shaft, J_L = J_M): the closed loop's lowest mode is at 7.53 Hz, zeta 0.026
SOFT = {
    "position_loop": {"bandwidth_hz": 2.0},
    "velocity_loop": {"bandwidth_hz": 20.0},
    "current_loop": {"bandwidth_hz": 800.0},
    "motor": MOTOR,
}
JERK_PROFILE = {"time_s": [0, 0.05, 0.1, 0.2, 0.25, 0.3, 0.6], "jerk": [400, -400, 0, -400, 400, 0, 0]}


def _simulate(client, plant=CUSIMANO, drive=SOFT, profile=JERK_PROFILE):
    return client.post("/v1/simulate", json={"plant": plant, "profile": profile, "hold": "zero", "drive": drive})


def test_simulate_through_the_drive_is_the_core_model(client):
    """The answer's closed loop is models.servo_response's, to the bit, with the gains of the named rules."""
    body = _simulate(client).json()
    motor = Motor(0.9, 0.015, 0.8, max_torque_nm=10.0)
    drive = Drive(2 * math.pi * 2.0, velocity_pi(20.0, 0.01), current_pi(800.0, motor), motor)
    t = np.array(JERK_PROFILE["time_s"], dtype=float)
    core = simulate_drive(
        example_plants()["cusimano_8hz_equal_inertia"],
        drive,
        PiecewiseCommand.from_held_steps(t, JERK_PROFILE["jerk"], 3),
    )
    closed = body["closed_loop"]
    assert closed["load"]["position"] == pytest.approx(core.load.load_position.tolist(), rel=1e-12, abs=1e-15)
    assert closed["motor"]["torque_nm"] == pytest.approx(core.torque_nm.tolist(), rel=1e-12, abs=1e-15)
    gains = closed["gains"]
    omega_i, omega_v = 2 * math.pi * 800.0, 2 * math.pi * 20.0
    assert gains["current_kp"] == pytest.approx(0.015 * omega_i) and gains["current_ki"] == pytest.approx(0.9 * omega_i)
    assert gains["velocity_kp"] == pytest.approx(0.01 * omega_v) and gains["velocity_ki"] == pytest.approx(
        0.01 * omega_v**2 / 2
    )
    assert closed["modes"][0]["natural_frequency_hz"] == pytest.approx(7.527, abs=1e-3)
    assert closed["saturated"] is False and closed["saturation"] == []
    ideal = np.array(body["load"]["position"])
    assert closed["difference"]["load_position_max_abs"] == pytest.approx(
        float(np.max(np.abs(np.array(closed["load"]["position"]) - ideal)))
    )


def test_bad_drives_are_422s_that_name_the_field(client):
    unstable = copy.deepcopy(SOFT)
    unstable["velocity_loop"] = {"bandwidth_hz": 80.0}
    unstable["position_loop"] = {"bandwidth_hz": 15.0}
    answer = _simulate(client, drive=unstable)
    assert answer.status_code == 422
    assert (
        answer.json()["field"] == "drive" and "unstable" in answer.json()["detail"] and "Hz" in answer.json()["detail"]
    )
    both = {**SOFT, "velocity_loop": {"bandwidth_hz": 20.0, "kp": 1.0, "ki": 1.0}}
    answer = _simulate(client, drive=both)
    assert answer.status_code == 422 and answer.json()["field"].startswith("drive.velocity_loop")
    mode = {"kind": "mode", "natural_frequency_hz": 8.0}
    answer = _simulate(client, plant=mode)
    assert answer.status_code == 422 and answer.json()["field"] == "drive.motor.inertia_kgm2"
    answer = client.post(
        "/v1/plants/analyze", json={"plant": {"kind": "closed_loop", "mechanics": CUSIMANO, "drive": unstable}}
    )
    assert answer.status_code == 422 and answer.json()["field"] == "plant.drive"


def test_a_torque_the_command_drives_past_the_limit_is_reported_and_simulated(client):
    """The linear loop would need 0.30 N m of a 0.1 N m motor: the answer is the drive at its limit
    (models.servo_limits, checked against the equations in tests/models/test_servo_limits.py), which says so."""
    weak = copy.deepcopy(SOFT)
    weak["motor"]["max_torque_nm"] = 0.1
    closed = _simulate(client, drive=weak).json()["closed_loop"]
    assert closed["saturated"] is True and closed["simulation"] == "limited" and closed["simulation_note"] is None
    (saturation,) = closed["saturation"]
    assert saturation["quantity"] == "torque_nm" and saturation["limit"] == 0.1
    assert saturation["peak"] > 0.1  # what the command needs through an unlimited drive
    assert max(abs(x) for x in closed["motor"]["torque_nm"]) <= 0.1  # what the motor gives (the current follows)
    linear = _simulate(client).json()["closed_loop"]
    assert linear["simulation"] == "linear" and linear["saturated"] is False
    assert closed["metrics"]["settling_time_s"] != linear["metrics"]["settling_time_s"]


def _lowest_mode_residual(metrics: dict) -> float:
    """The residual at the closed loop's lowest mode (7.53 Hz): the one every family here designs for."""
    return min(metrics["modes"], key=lambda mode: mode["natural_frequency_hz"])["residual_amplitude"]


@pytest.mark.parametrize(
    ("family", "options", "every_mode"),
    [
        ("time-optimal", {}, True),
        ("input-shaped", {"shaped_modes": "all"}, True),
        ("stap", {}, False),
        ("smoother", {}, False),
    ],
)
def test_designing_through_the_soft_loop_leaves_10x_less_residual(client, family, options, every_mode):
    """The same family designed for the mechanics (an ideal motor) and for the closed loop, each design's command
    then run through the drive (``drive``: the answer's closed_loop block, on the design's exact command): the
    closed loop's design cancels the mode the machine has (7.53 Hz, zeta 0.026), the other the shaft's 8 Hz. STAP
    and the smoother design for one mode: the closed loop's second (21.9 Hz, zeta 0.90) is left to its damping, so
    they are compared at the mode they design for; the others at every mode."""
    move = {"displacement": 0.5, "limits": {"max_velocity": 2.0, "max_acceleration": 20.0}}
    through = {"kind": "closed_loop", "mechanics": CUSIMANO, "drive": SOFT}
    ideal = client.post(f"/v1/profiles/{family}", json={"plant": CUSIMANO, "drive": SOFT, **move, **options})
    closed = client.post(f"/v1/profiles/{family}", json={"plant": through, **move, **options})
    assert ideal.status_code == 200 and closed.status_code == 200, (ideal.text, closed.text)
    mistuned_metrics, tuned_metrics = ideal.json()["closed_loop"]["metrics"], closed.json()["metrics"]
    measure = (lambda m: m["residual_amplitude"]) if every_mode else _lowest_mode_residual
    mistuned, tuned = measure(mistuned_metrics), measure(tuned_metrics)
    assert mistuned > 1e-6 * 0.5  # the ideal design rings through the drive (not round-off: 1e-16 of the move)
    assert mistuned >= 10 * tuned, (mistuned, tuned)


def test_a_closed_loop_plant_takes_no_second_drive(client):
    through = {"kind": "closed_loop", "mechanics": CUSIMANO, "drive": SOFT}
    answer = client.post("/v1/profiles/time-optimal", json={"plant": through, "drive": SOFT, "displacement": 0.5})
    assert answer.status_code == 422 and answer.json()["field"] == "drive"


def test_compare_ranks_the_designs_by_their_settling_through_the_drive(client):
    """Each row's command through the soft loop: its closed-loop summary is the profile endpoint's closed_loop
    block for that row's request, and the rows are ranked by it (never-settling last)."""
    move = {"displacement": 0.5, "limits": {"max_velocity": 2.0, "max_acceleration": 20.0}}
    body = {"plant": CUSIMANO, "drive": SOFT, **move, "families": ["time_optimal", "input_shaped", "smoother"]}
    answer = client.post("/v1/compare", json=body)
    assert answer.status_code == 200, answer.text
    rows = answer.json()["rows"]
    settle = [row["closed_loop"]["settling_time_s"] for row in rows]
    finite = [s for s in settle if s is not None]
    assert len(finite) >= 2  # (the soft loop damps every design: each settles, the ranking is not vacuous)
    assert finite == sorted(finite) and settle[: len(finite)] == finite  # never-settling rows last
    first = rows[0]
    alone = client.post(first["endpoint"], json={**first["request"], "drive": SOFT}).json()["closed_loop"]["metrics"]
    assert first["closed_loop"]["settling_time_s"] == alone["settling_time_s"]
    assert first["closed_loop"]["residual_amplitude"] == pytest.approx(alone["residual_amplitude"], rel=1e-12)
    through = {"kind": "closed_loop", "mechanics": CUSIMANO, "drive": SOFT}
    refused = client.post("/v1/compare", json={**body, "plant": through})
    assert refused.status_code == 422 and refused.json()["field"] == "drive"


def test_the_closed_loop_metrics_peak_torque_is_the_drives(client):
    """closed_loop.metrics.peak_motor_torque_nm means what it says: the peak |K_T i| of closed_loop.motor."""
    closed = _simulate(client).json()["closed_loop"]
    assert closed["metrics"]["peak_motor_torque_nm"] == max(abs(x) for x in closed["motor"]["torque_nm"])
    assert closed["metrics"]["percentage_vibration"] is None  # /v1/simulate has no reference move (nor metrics' V)


def test_the_percentage_vibration_through_the_drive_is_of_the_unshaped_move_through_it(client):
    """V through the drive means what V means on the ideal motor, through the drive: 100 x the design's residual
    over the unshaped rigid command's under the same limits (here the trapezoidal velocity at 2 rad/s and
    20 rad/s^2: 0.1 s ramps, 0.15 s at speed), that command written here and run through /v1/simulate."""
    move = {"displacement": 0.5, "limits": {"max_velocity": 2.0, "max_acceleration": 20.0}}
    design = client.post("/v1/profiles/input-shaped", json={"plant": CUSIMANO, "drive": SOFT, **move, "shaper": "zv"})
    closed = design.json()["closed_loop"]["metrics"]
    unshaped = {"time_s": [0.0, 0.1, 0.25, 0.35, 0.5], "acceleration": [20.0, 0.0, -20.0, 0.0, 0.0]}
    body = {"plant": CUSIMANO, "drive": SOFT, "profile": unshaped, "hold": "zero", "held_quantity": "acceleration"}
    reference = client.post("/v1/simulate", json=body)
    assert reference.status_code == 200, reference.text
    base = reference.json()["closed_loop"]["metrics"]["residual_amplitude"]
    assert base > 1e-3  # the unshaped move rings through the drive
    assert closed["percentage_vibration"] == pytest.approx(100 * closed["residual_amplitude"] / base, rel=1e-9)
    assert 1.0 < closed["percentage_vibration"] < 100.0  # ZV for the shaft, detuned by the loop: some, not all


def test_compare_chooses_each_familys_design_by_its_settling_through_the_drive(client):
    """The smoother family offers two tuned chains and compare keeps one. On the ideal motor the exponential one
    settles first (0.375 s against 0.4375 s); through the soft loop the damped harmonic one does (2.52 s against
    2.86 s), so that is the row compare keeps with the drive: the choice, not only the ranking, is the drive's."""
    move = {"displacement": 0.5, "limits": {"max_velocity": 2.0, "max_acceleration": 20.0}}
    settle = {}
    for kind in ("damped_harmonic", "exponential"):
        body = {"plant": CUSIMANO, "drive": SOFT, **move, "filters": [{"type": kind}]}
        answer = client.post("/v1/profiles/smoother", json=body).json()
        settle[kind] = (answer["metrics"]["settling_time_s"], answer["closed_loop"]["metrics"]["settling_time_s"])
    assert settle["exponential"][0] < settle["damped_harmonic"][0]  # ideal: exponential first
    assert settle["damped_harmonic"][1] < settle["exponential"][1]  # through the drive: damped harmonic first
    ideal = client.post("/v1/compare", json={"plant": CUSIMANO, **move, "families": ["smoother"]}).json()["rows"]
    through = client.post("/v1/compare", json={"plant": CUSIMANO, "drive": SOFT, **move, "families": ["smoother"]})
    (row,) = through.json()["rows"]
    assert [r["label"] for r in ideal] == ["smoother/exponential"] and row["label"] == "smoother/damped_harmonic"
    assert row["closed_loop"]["settling_time_s"] == settle["damped_harmonic"][1]


def test_a_drive_still_at_its_limit_when_the_command_ends_is_followed_past_the_end(client):
    """The same move cut at its last change (0.3 s): the 0.1 N m motor is still behind and at its limit then, so
    the closed loop's arrays go on past the command's end (the command holding its final position) until the
    drive provably stays within its limit, its metrics from there; the difference from the ideal motor is taken
    at those instants too."""
    weak = copy.deepcopy(SOFT)
    weak["motor"]["max_torque_nm"] = 0.1
    cut = {"time_s": JERK_PROFILE["time_s"][:-1], "jerk": JERK_PROFILE["jerk"][:-1]}
    answer = _simulate(client, drive=weak, profile=cut)
    assert answer.status_code == 200, answer.text
    closed = answer.json()["closed_loop"]
    time = closed["motor"]["time_s"]
    assert closed["simulation"] == "limited" and time[-1] > 0.3 and time[: len(cut["time_s"])] == cut["time_s"]
    assert len(closed["load"]["position"]) == len(time) == len(closed["motor"]["torque_nm"])
    assert max(abs(x) for x in closed["motor"]["torque_nm"]) <= 0.1
    assert closed["load"]["position"][-1] == pytest.approx(0.2, abs=0.01)  # back on the target (0.2 rad)
    assert 0.0 < closed["difference"]["load_position_max_abs"] < 0.2
    assert closed["metrics"]["settling_time_s"] is not None


def test_a_reference_the_drive_cannot_run_leaves_v_unknown_not_the_answer(client):
    """Rest-to-velocity without an acceleration limit: V's reference is a velocity step, which the simulation
    refuses beside the loop's slow pole. That is the service's reference, not the user's design: the design is
    answered through the drive, with V null."""
    body = {"plant": CUSIMANO, "target_velocity": 2.0, "shaper": "zv", "drive": SOFT}
    answer = client.post("/v1/profiles/input-shaped", json=body)
    assert answer.status_code == 200, answer.text
    closed = answer.json()["closed_loop"]
    assert closed["metrics"]["percentage_vibration"] is None
    assert closed["metrics"]["residual_velocity_amplitude"] >= 0.0
