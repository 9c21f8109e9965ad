"""The worked examples of POST /v1/profiles/time-optimal (its OpenAPI examples; the warm-up designs them)."""

from __future__ import annotations

from typing import Any

from app.examples import CUSIMANO_8HZ, SOFT_DRIVE

_40HZ = {"plant": {"kind": "mode", "natural_frequency_hz": 40.0, "damping_ratio": 0.0}, "displacement": 0.12}
_LIMITS = {"max_velocity": 5.0, "max_acceleration": 10.0}

EXAMPLES: dict[str, dict[str, Any]] = {
    "known_answer": {
        "summary": "One undamped 40 Hz mode, 0.12 m at 10 m/s^2: 219.7077 ms (arcs +104.03, -5.83, +5.83, -104.03 ms)",
        "description": "The closed-form symmetric three-switch solution; the rigid bang-bang move takes 219.09 ms.",
        "value": {**_40HZ, "limits": _LIMITS},
    },
    "robust_band": {
        "summary": "The same, robust: V <= 5 % for a true frequency within +-10 %",
        "value": {**_40HZ, "limits": _LIMITS, "robustness": {"frequency_ratio_range": [0.9, 1.1]}},
    },
    "zvd_like": {
        "summary": "Zero residual and zero frequency derivative at the mode (ZVD-like), damped 5 Hz, with a cruise",
        "value": {
            "plant": {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": 0.05},
            "displacement": 0.3,
            "limits": {"max_velocity": 1.0, "max_acceleration": 10.0},
            "robustness": {"derivative_order": 1},
        },
    },
    "jerk_limited": {
        "summary": "Jerk-limited: the jerk is piecewise constant (5 Hz, zeta = 0.05)",
        "value": {
            "plant": {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": 0.05},
            "displacement": 0.3,
            "limits": {"max_velocity": 1.0, "max_acceleration": 10.0, "max_jerk": 200.0},
        },
    },
    "in_motion": {
        "summary": "Starting and ending in motion: from 0.2 m/s to 0.1 m/s over 0.3 m, the load still vibration-free",
        "description": "initial_state / final_state chain moves: each starts where the previous one ended (the load "
        "quasi-static in that motion).",
        "value": {
            "plant": {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": 0.05},
            "displacement": 0.3,
            "limits": {"max_velocity": 0.5, "max_acceleration": 3.0},
            "initial_state": {"velocity": 0.2},
            "final_state": {"velocity": 0.1},
        },
    },
    "through_a_drive": {
        "summary": "Designed through a soft drive: Cusimano's 8 Hz shaft under a 20 Hz velocity loop",
        "description": "The closed_loop plant is the closed loop from the command to the load: its mode (7.53 Hz, "
        "zeta 0.026) is cancelled, not the shaft's 8 Hz (docs/drive.md).",
        "value": {
            "plant": {"kind": "closed_loop", "mechanics": CUSIMANO_8HZ, "drive": SOFT_DRIVE},
            "displacement": 0.5,
            "limits": {"max_velocity": 2.0, "max_acceleration": 20.0},
        },
    },
    "tradeoff": {
        "summary": "What robustness costs: the minimum duration for bands of +-0, 5, 10, 15, 20 %",
        "value": {**_40HZ, "limits": _LIMITS, "tradeoff": [0, 0.05, 0.1, 0.15, 0.2]},
    },
    "two_inertia_torque": {
        "summary": "Two-inertia plant (8 Hz) under a 10 N m motor torque limit (Cusimano Table 2 motor)",
        "value": {
            "plant": {
                "kind": "two_inertia",
                "motor_inertia_kgm2": 0.005,
                "load_inertia_kgm2": 0.005,
                "stiffness_nm_per_rad": 12.633093633,
                "damping_nms_per_rad": 0.0,
            },
            "displacement": 3.0,
            "limits": {"max_velocity": 150.0, "max_torque_nm": 10.0},
        },
    },
}
