"""The worked examples of POST /v1/compare (its OpenAPI examples)."""

from __future__ import annotations

from typing import Any

from app.examples import CUSIMANO_8HZ, INCERTI_TABLE_III

EXAMPLES: dict[str, dict[str, Any]] = {
    "incerti_rest_to_rest": {
        "summary": "Incerti Table III platform: 15 motor revolutions within velocity and acceleration limits",
        "value": {
            "plant": INCERTI_TABLE_III,
            "displacement": 94.24777960769379,
            "limits": {"max_velocity": 200.0, "max_acceleration": 700.0},
        },
    },
    "cusimano_rest_to_velocity": {
        "summary": "Cusimano 8 Hz two-inertia plant: up to 150 rad/s within the 10 N m motor",
        "value": {"plant": CUSIMANO_8HZ, "target_velocity": 150.0, "limits": {"max_torque_nm": 10.0}},
    },
}
