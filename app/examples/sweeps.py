"""The worked examples of POST /v1/sweeps (its OpenAPI examples)."""

from __future__ import annotations

from typing import Any

EXAMPLES: dict[str, dict[str, Any]] = {
    "time_optimal_frequency": {
        "summary": "The README's 40 Hz time-optimal move, for 38 to 42 Hz (5 plants), refined where too coarse",
        "value": {
            "family": "time-optimal",
            "request": {
                "plant": {"kind": "mode", "natural_frequency_hz": 40.0, "damping_ratio": 0.0},
                "displacement": 0.12,
                "limits": {"max_velocity": 5.0, "max_acceleration": 10.0},
            },
            "axes": [{"path": "plant.natural_frequency_hz", "start": 38.0, "stop": 42.0, "num": 5}],
            "refine": True,
            "max_refined_points": 4,
        },
    },
    "zv_payload": {
        "summary": "A ZV-shaped velocity step over the payload of a two-inertia drive",
        "value": {
            "family": "input-shaped",
            "request": {
                "plant": {
                    "kind": "two_inertia",
                    "motor_inertia_kgm2": 0.005,
                    "load_inertia_kgm2": 0.005,
                    "stiffness_nm_per_rad": 12.633093633,
                },
                "target_velocity": 100.0,
                "shaper": "zv",
            },
            "axes": [{"path": "plant.load_inertia_kgm2", "start": 0.004, "stop": 0.008, "num": 9, "scale": "log"}],
        },
    },
}
