"""The CSV table for drives against the JSON answer it is made from, side by side in one run.

For one STAP design sampled at 2k, 20k and 100k instants: the time to build the uniform table (every column
evaluated at t_k = k * period: optim.tables) and write it (app.responses.csv_body), against orjson writing the
whole JSON answer, and the design itself. Target: the default CSV costs at most 2.5 times the JSON answer
(both scale with the samples; the CSV writes 5 of the JSON's 11 arrays, but evaluates them at the instants
and finds its line breaks), and less than the design itself.

Run: python bench/csv_export.py
"""

from __future__ import annotations

import statistics
import time

from app.encoding import dumps
from app.responses import csv_body
from app.settings import Settings
from optim import tables
from vibfree import synthesize

SETTINGS = Settings(max_samples=200_000)
BASE = {"plant": {"kind": "mode", "natural_frequency_hz": 40.0, "damping_ratio": 0.02}, "target_velocity": 150.0}


def best_of(call, repeats: int = 7) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        call()
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def main() -> None:
    print(f"{'rows':>8s} {'design s':>9s} {'JSON s':>8s} {'CSV s':>8s} {'CSV all cols s':>14s} {'CSV/JSON':>9s}")
    for rows in (2_000, 20_000, 100_000):
        horizon = 0.175 + 5 / 40.0  # the command (t_a = 0.175 s) and 5 periods
        request = {**BASE, "limits": {"max_acceleration": 1000.0}, "sample_period_s": horizon / (rows - 1)}
        design_s = best_of(lambda r=request: synthesize("stap", r, settings=SETTINGS), repeats=3)
        design = synthesize("stap", request, settings=SETTINGS)
        json_s = best_of(lambda d=design: dumps(d.answer))
        csv_s = best_of(lambda d=design: csv_body(tables.table(d.result), []))
        all_s = best_of(lambda d=design: csv_body(tables.table(d.result, ("all",)), []))
        print(f"{rows:8d} {design_s:9.4f} {json_s:8.4f} {csv_s:8.4f} {all_s:14.4f} {csv_s / json_s:9.2f}")


if __name__ == "__main__":
    main()
