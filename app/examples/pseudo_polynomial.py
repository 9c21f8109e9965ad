"""The worked examples of POST /v1/profiles/pseudo-polynomial (its OpenAPI examples; the warm-up designs them)."""

from __future__ import annotations

from typing import Any

from app.examples import CUSIMANO_8HZ, INCERTI_TABLE_III

EXAMPLES: dict[str, dict[str, Any]] = {
    "incerti_table_iii": {
        "summary": "Incerti Sec. V: 15 motor revolutions in 1 s on the Table III platform",
        "description": "Starts from the quintic (3, 4, 5), which leaves about 3.5e-3 rad of platform vibration.",
        "value": {"plant": INCERTI_TABLE_III, "displacement": 94.24777960769379, "duration_s": 1.0},
    },
    "incerti_order_4": {
        "summary": "The same move with order 4 (derivatives up to the 4th null at both ends)",
        "value": {"plant": INCERTI_TABLE_III, "displacement": 94.24777960769379, "duration_s": 1.0, "order": 4},
    },
    "shortest_with_limits": {
        "summary": "Shortest move within acceleration and jerk limits (8 Hz two-inertia plant)",
        "value": {
            "plant": CUSIMANO_8HZ,
            "displacement": 10.0,
            "duration_s": 0.8,
            "limits": {"max_acceleration": 200.0, "max_jerk": 5000.0},
            "minimize_duration": True,
        },
    },
}
