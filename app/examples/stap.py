"""The worked examples of POST /v1/profiles/stap (its OpenAPI examples; the warm-up designs them)."""

from __future__ import annotations

from typing import Any

from app.examples import CUSIMANO_8HZ, CUSIMANO_40HZ

CUSIMANO_8HZ_LIGHT_LOAD: dict[str, Any] = {
    "kind": "two_inertia",
    "motor_inertia_kgm2": 0.005,
    "load_inertia_kgm2": 0.00125,
    "stiffness_nm_per_rad": 3.158273408,  # J_L (2 pi 8 Hz)^2 with J_L = J_M/4
    "damping_nms_per_rad": 0.0,
}
_SEC3 = {"plant": CUSIMANO_40HZ, "target_velocity": 150.0, "limits": {"max_acceleration": 1000.0}}

EXAMPLES: dict[str, dict[str, Any]] = {
    "section_3_k1": {
        "summary": "Sec. 3 (Fig. 14): 150 rad/s on a 40 Hz mode, a_Max = 1000 rad/s^2, k_j = 1",
        "description": "t_a,min = 0.15 s (eq. 21), t_j = 1/f_n,e = 0.025 s (eq. 50), t_a = 0.175 s (eq. 61): "
        "no residual.",
        "value": {**_SEC3, "jerk_periods": 1, "sensitivity": {"min_ratio": 0.5, "max_ratio": 1.5, "count": 201}},
    },
    "section_3_k3": {
        "summary": "Sec. 3 (Fig. 16): the same with k_j = 3 (t_j = 0.075 s, t_a = 0.225 s)",
        "value": {**_SEC3, "jerk_periods": 3},
    },
    "fig_17_side_band": {
        "summary": "Fig. 17: t_a = 0.165 s with the side band (k_j, delta) = (0, 1): "
        "t_j = dec(f_n,e t_a)/f_n,e = 0.015 s",
        "description": "Zero residual at f_n,e, but the load acceleration oscillates during t_c and the SC is poor "
        "(Appendix C: f_n,e t_a,min = 6 is whole and 0.15 <= t_a < 0.175).",
        "value": {**_SEC3, "acceleration_time_s": 0.165, "jerk_periods": 0, "delta": 1},
    },
    "table_2_torque_limit": {
        "summary": "Sec. 3: Table 2 motor (10 N m) with J_L = J_M at 8 Hz; the limit lowered for 0.9 f_n,e",
        "description": "a_Max = 10/(J_M + J_L) = 1000 rad/s^2 (eq. 19), t_a,min = 0.15 s; the torque oscillates "
        "by about 0.055 M at 0.9 f_n,e (eqs. 57-59), so the limit is lowered to 0.948 of it (the paper's 0.94).",
        "value": {
            "plant": CUSIMANO_8HZ,
            "target_velocity": 150.0,
            "limits": {"max_torque_nm": 10.0},
            "jerk_periods": 1,
        },
    },
    "table_2_light_load": {
        "summary": "Sec. 3: the same motor with J_L = J_M/4: a triangle peaking at 1200 rad/s^2 (eq. 31)",
        "value": {
            "plant": CUSIMANO_8HZ_LIGHT_LOAD,
            "target_velocity": 150.0,
            "limits": {"max_torque_nm": 10.0},
            "jerk_periods": 1,
        },
    },
    "auto": {
        "summary": "The Fig. 25 flowchart: k_j chosen for a 10 % frequency uncertainty and a 5 % residual",
        "value": {**_SEC3, "frequency_uncertainty": 0.1, "residual_tolerance": 0.05},
    },
    "damped_optimized": {
        "summary": "A damped 40 Hz mode (zeta = 0.1), t_a = 0.2 s: IPOPT over t_j beats the k_j = 1 closed form",
        "value": {
            **_SEC3,
            "plant": {"kind": "mode", "natural_frequency_hz": 40.0, "damping_ratio": 0.1},
            "acceleration_time_s": 0.2,
            "jerk_periods": 1,
            "method": "optimized",
        },
    },
    "robust_optimized": {
        "summary": "Worst case over +-20 % of f_n,e and zeta in {0, 0.05}, at t_a = 0.2 s",
        "value": {
            **_SEC3,
            "acceleration_time_s": 0.2,
            "method": "optimized",
            "frequency_uncertainty": 0.2,
            "optimization": {"objective": "worst_case", "damping_ratios": [0.0, 0.05]},
        },
    },
    "rest_to_rest": {
        "summary": "Rest-to-rest: 30 rad at up to 150 rad/s on the 40 Hz mode (two k_j = 1 ramps and a cruise)",
        "value": {
            "plant": CUSIMANO_40HZ,
            "displacement": 30.0,
            "limits": {"max_acceleration": 1000.0, "max_velocity": 150.0},
            "jerk_periods": 1,
        },
    },
}
