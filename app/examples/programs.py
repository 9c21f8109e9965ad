"""The worked examples of POST /v1/programs (its OpenAPI examples; bench/programs.py runs the pick-and-place)."""

from __future__ import annotations

from typing import Any

Y_HZ = 22.0  # the Y axis's mode in the middle of X's travel; +-15 % at its ends
PICK_AND_PLACE: dict[str, Any] = {
    "axes": [
        {
            "name": "x",
            "plant": {"kind": "mode", "natural_frequency_hz": 14.0, "damping_ratio": 0.03},
            "limits": {"max_velocity": 1.5, "max_acceleration": 15.0, "max_jerk": 1500.0},
        },
        {
            "name": "y",
            "plant_table": {
                "coordinate": "x",
                "points": [
                    {"at": 0.0, "plant": {"kind": "mode", "natural_frequency_hz": 0.85 * Y_HZ, "damping_ratio": 0.02}},
                    {"at": 0.25, "plant": {"kind": "mode", "natural_frequency_hz": Y_HZ, "damping_ratio": 0.02}},
                    {"at": 0.5, "plant": {"kind": "mode", "natural_frequency_hz": 1.15 * Y_HZ, "damping_ratio": 0.02}},
                ],
            },
            "limits": {"max_velocity": 1.5, "max_acceleration": 12.0, "max_jerk": 1200.0},
        },
    ],
    "start": {"x": 0.0, "y": 0.0},
    "moves": [
        {"target": {"x": x, "y": y}, "coordination": "synchronized", "dwell_s": 0.05}
        for x, y in [
            (0.05, 0.05),
            (0.45, 0.15),
            (0.15, 0.25),
            (0.40, 0.05),
            (0.10, 0.20),
            (0.35, 0.25),
            (0.25, 0.10),
            (0.0, 0.0),
        ]
    ],
}

EXAMPLES: dict[str, dict[str, Any]] = {
    "straight_line": {
        "summary": "Two axes, a straight line there and back: both modes cancelled on the path",
        "value": {
            "axes": [
                {
                    "name": "x",
                    "plant": {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": 0.05},
                    "limits": {"max_velocity": 1.0, "max_acceleration": 4.0},
                },
                {
                    "name": "y",
                    "plant": {"kind": "mode", "natural_frequency_hz": 7.0, "damping_ratio": 0.02},
                    "limits": {"max_velocity": 0.8, "max_acceleration": 3.0},
                },
            ],
            "start": {"x": 0.0, "y": 0.0},
            "moves": [
                {"target": {"x": 0.3, "y": 0.1}, "coordination": "straight_line", "dwell_s": 0.2},
                {"target": {"x": 0.0, "y": 0.0}, "coordination": "synchronized"},
            ],
        },
    },
    "pick_and_place": {
        "summary": "An 8-stop pick-and-place cycle; Y's mode changes by +-15 % with X (bench/programs.py)",
        "value": PICK_AND_PLACE,
    },
}
