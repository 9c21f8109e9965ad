"""The moves of bench/time_optimal.py, their exact minimum times (tests/time_optimal_oracle.py), posts and defects."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

from tests.time_optimal_oracle import OutOfRange, minimum_time, rigid_minimum_time, velocity_limited_upper_bound

DEFECTS: list[str] = []


@dataclass(frozen=True)
class Move:
    name: str
    hz: float
    zeta: float
    d: float
    a: float
    v: float
    j: float  # jerk limit for part c

    @property
    def plant(self) -> dict[str, Any]:
        return {"kind": "mode", "natural_frequency_hz": self.hz, "damping_ratio": self.zeta}

    @property
    def limits(self) -> dict[str, float]:
        return {"max_velocity": self.v, "max_acceleration": self.a}

    @property
    def rigid_s(self) -> float:
        return rigid_minimum_time(self.a, self.v, self.d)

    @property
    def periods(self) -> float:
        return self.rigid_s * self.hz


MOVES = [
    Move("2Hz short", 2.0, 0.0, 0.08, 2.0, 1.0, 40.0),  # bang-bang 0.4 s: 0.8 periods
    Move("10Hz z.1", 10.0, 0.1, 0.1, 20.0, 2.0, 2000.0),  # bang-bang 0.141 s: 1.4 periods
    Move("40Hz 3.6T", 40.0, 0.0, 0.02, 10.0, 5.0, 2000.0),  # bang-bang 89 ms: 3.6 periods
    Move("5Hz z.05 cst", 5.0, 0.05, 0.5, 5.0, 0.6, 100.0),  # trapezoid 0.953 s: 4.8 periods
    Move("10Hz cst", 10.0, 0.0, 0.53, 20.0, 1.0, 1000.0),  # trapezoid 0.58 s: 5.8 periods
    Move("40Hz known", 40.0, 0.0, 0.12, 10.0, 5.0, 1000.0),  # bang-bang 219 ms: 8.8 periods (219.7077 ms)
]


def defect(text: str) -> None:
    DEFECTS.append(text)


def post(client: Any, path: str, body: dict[str, Any]) -> tuple[dict[str, Any] | None, float]:
    start = time.perf_counter()
    answer = client.post(path, json=body)
    elapsed = time.perf_counter() - start
    if answer.status_code != 200:
        detail = answer.json() if answer.headers.get("content-type", "").endswith("json") else answer.text
        defect(f"{path} {answer.status_code}: {str(detail)[:300]} for {str(body)[:200]}")
        return None, elapsed
    return answer.json(), elapsed


def base_body(move: Move, **extra: Any) -> dict[str, Any]:
    return {"plant": move.plant, "displacement": move.d, "limits": move.limits, **extra}


def oracle_s(move: Move) -> tuple[float | None, float | None]:
    """(exact minimum, upper bound): the exact minimum for undamped moves without coast, else for undamped moves
    the oracle's feasible bound where the velocity limit is active (an answer slower than it is not optimal)."""
    if move.zeta != 0.0:
        return None, None
    w = 2 * math.pi * move.hz
    try:
        return minimum_time(w, move.a, move.v, move.d), None
    except OutOfRange:
        return None, velocity_limited_upper_bound(w, move.a, move.v, move.d)
