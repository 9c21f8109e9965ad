"""Worked examples for the OpenAPI docs page, taken from the papers' plants."""

from __future__ import annotations

import math
from typing import Any

INCERTI_TABLE_III: dict[str, Any] = {
    "kind": "belt_platform",
    "platform_inertia_kgm2": 6.0,
    "branch_stiffness_n_per_m": 90000.0,
    "branch_damping_ns_per_m": 150.0,
    "motor_pulley_radius_m": 0.06,
    "platform_pulley_radius_m": 0.18,
    "gear_ratio": 0.1,
}
CUSIMANO_8HZ: dict[str, Any] = {
    "kind": "two_inertia",
    "motor_inertia_kgm2": 0.005,
    "load_inertia_kgm2": 0.005,
    "stiffness_nm_per_rad": 12.63309363339438,  # J_L (2 pi 8 Hz)^2
    "damping_nms_per_rad": 0.0,
}
CHATLATANAGULCHAI_EQ3: dict[str, Any] = {
    "kind": "rigid_flexible",
    "drive_mass_kg": 2.0,
    "load_mass_kg": 3.0,
    "stiffness_n_per_m": 1.0,
    "damping_ns_per_m": 0.1,
    "drive_damping_ns_per_m": 30.0,
}
# sigma = -15.6539 1/s, Omega = 122.7185 rad/s (Biagiotti Sec. VI): omega_n = 123.7129 rad/s, zeta = 0.126534
BIAGIOTTI_MODE: dict[str, Any] = {"kind": "mode", "natural_frequency_hz": 19.6895152, "damping_ratio": 0.1265341}
CUSIMANO_40HZ: dict[str, Any] = {"kind": "mode", "natural_frequency_hz": 40.0, "damping_ratio": 0.0}
# Table 2's motor in a velocity-mode drive (Fig. 20), its gains by the named rules (docs/drive.md)
CUSIMANO_MOTOR: dict[str, Any] = {
    "resistance_ohm": 0.9,
    "inductance_h": 0.015,
    "torque_constant_nm_per_a": 0.8,
    "max_torque_nm": 10.0,
}
CUSIMANO_DRIVE: dict[str, Any] = {
    "position_loop": None,
    "velocity_loop": {"bandwidth_hz": 100.0},
    "current_loop": {"bandwidth_hz": 2500.0},
    "motor": CUSIMANO_MOTOR,
}
# A soft velocity loop on the 8 Hz shaft: the closed loop rings at 7.53 Hz, zeta 0.026
SOFT_DRIVE: dict[str, Any] = {
    "position_loop": {"bandwidth_hz": 2.0},
    "velocity_loop": {"bandwidth_hz": 20.0},
    "current_loop": {"bandwidth_hz": 800.0},
    "motor": CUSIMANO_MOTOR,
}

PLANT_EXAMPLES: dict[str, dict[str, Any]] = {
    "incerti_belt_platform": {
        "summary": "Incerti Table III belt-driven platform",
        "description": "omega_n = 31.1769 rad/s, xi = 0.025981, lambda = 1/30.",
        "value": {"plant": INCERTI_TABLE_III},
    },
    "cusimano_two_inertia": {
        "summary": "Cusimano 8 Hz two-inertia plant (Table 2 motor, J_L = J_M)",
        "value": {"plant": CUSIMANO_8HZ},
    },
    "chatlatanagulchai_rigid_flexible": {
        "summary": "Chatlatanagulchai eq. (3) plant",
        "description": "omega_n = 0.57703 rad/s, zeta = 0.057724 (eq. 3 as printed).",
        "value": {"plant": CHATLATANAGULCHAI_EQ3},
    },
    "biagiotti_mode": {
        "summary": "Biagiotti identified mode (omega_n = 123.71 rad/s, delta = 0.1265)",
        "value": {"plant": BIAGIOTTI_MODE},
    },
    "transfer_function": {
        "summary": "A transfer function: modes at 5 Hz (zeta 0.02) and 23 Hz (zeta 0.03), unit DC gain",
        "value": {
            "plant": {
                "kind": "transfer_function",
                "numerator": [20611800.0],
                "denominator": [1.0, 9.92743, 21881.9, 34801.4, 20611800.0],
            }
        },
    },
}

SIMULATE_EXAMPLES: dict[str, dict[str, Any]] = {
    "cusimano_stap_40hz": {
        "summary": "Cusimano Sec. 3: STAP to 150 rad/s on a 40 Hz mode (k_j = 1)",
        "description": "Trapezoidal acceleration with t_j = 1/f_n = 0.025 s and t_a = 0.175 s, sampled at its "
        "corners: a first-order hold on the acceleration describes it exactly, and the residual is zero.",
        "value": {
            "plant": CUSIMANO_40HZ,
            "profile": {
                "time_s": [0.0, 0.025, 0.15, 0.175, 0.3],
                "acceleration": [0.0, 1000.0, 1000.0, 0.0, 0.0],
            },
        },
    },
    "through_a_drive": {
        "summary": "Through the drive: a held-jerk move on Cusimano's 8 Hz shaft under a soft 20 Hz velocity loop",
        "description": "The answer's closed_loop block: the motor, its current and torque, the load and the tracking "
        "error through the drive, its metrics beside the ideal motor's (docs/drive.md).",
        "value": {
            "plant": CUSIMANO_8HZ,
            "profile": {
                "time_s": [0.0, 0.05, 0.1, 0.2, 0.25, 0.3, 0.6],
                "jerk": [400.0, -400.0, 0.0, -400.0, 400.0, 0.0, 0.0],
            },
            "hold": "zero",
            "drive": SOFT_DRIVE,
        },
    },
    "chatlatanagulchai_zvd_step": {
        "summary": "Chatlatanagulchai Sec. 3.1: ZVD-shaped unit velocity step on the eq. (3) plant",
        "description": "A staircase velocity command (zero-order hold) with the ZVD amplitudes and times.",
        "value": {
            "plant": CHATLATANAGULCHAI_EQ3,
            "profile": {"time_s": [0.0, 5.45352, 10.90705, 60.0], "velocity": [0.29732, 0.79323, 1.0, 1.0]},
            "hold": "zero",
        },
    },
}

# Biagiotti Sec. VI: the identified plant
SIGMA_1_S = -15.6539  # identified decay (the paper's sigma)
OMEGA_RAD_S = 122.7185  # identified damped frequency
_OMEGA_N = math.hypot(SIGMA_1_S, OMEGA_RAD_S)
BIAGIOTTI_PLANT: dict[str, Any] = {
    "kind": "mode",
    "natural_frequency_hz": round(_OMEGA_N / (2 * math.pi), 10),  # 19.6895151859 Hz
    "damping_ratio": round(-SIGMA_1_S / _OMEGA_N, 10),  # 0.1265341244
}
T0_S = 2 * math.pi / OMEGA_RAD_S  # 0.0512 s
# Biagiotti Sec. VI's controller, as the paper describes it: a PID position loop with feed-forward run on a PC
# every 500 us, the current loop in the LinMot drive. The paper gives no gains or masses: a P-PI cascade is a PID
# on the position error (P = kv kp + ki, I = ki kp, D = kv), here 3 Hz and 15 Hz (symmetric optimum) on an
# assumed 0.5 kg moving mass, with velocity and acceleration feed-forward; the current loop ideal.
BIAGIOTTI_DRIVE: dict[str, Any] = {
    "sample_period_s": 0.0005,
    "position_loop": {"bandwidth_hz": 3.0},
    "velocity_loop": {"bandwidth_hz": 15.0},
    "current_loop": None,
    "motor": {
        "resistance_ohm": 4.0,
        "inductance_h": 0.002,
        "torque_constant_nm_per_a": 10.0,
        "max_torque_nm": 200.0,
        "inertia_kgm2": 0.5,
    },
}
