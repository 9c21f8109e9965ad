"""Benchmark: /v1/compare on its OpenAPI examples, and the pseudo-polynomial duration search it runs.

Figures for README.md (issue 11's target: compare answers its examples in at most 1 s p50 on the
2-core development machine). Compare is timed through the app with its solver pool (in-process
client, so the figure is the service's work, not the loopback's); the duration search in-process,
next to one fixed-duration solve of the same problem as the reference measured in the same run.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from fastapi.testclient import TestClient  # noqa: E402

from app.main import app  # noqa: E402
from app.routers.compare import EXAMPLES, CompareIn  # noqa: E402
from app.settings import Settings  # noqa: E402
from optim.families.pseudo_polynomial import PseudoPolynomialOptions  # noqa: E402
from optim.family import FAMILIES  # noqa: E402

RUNS = 15


def p50_ms(samples: list[float]) -> float:
    return 1e3 * statistics.median(samples)


def compare_examples() -> None:
    with TestClient(app) as client:
        while client.get("/readyz").status_code != 200:
            time.sleep(0.2)
        for name, example in EXAMPLES.items():
            body = example["value"]
            client.post("/v1/compare", json=body)  # first call: worker caches
            times = []
            for _ in range(RUNS):
                start = time.perf_counter()
                answer = client.post("/v1/compare", json=body)
                times.append(time.perf_counter() - start)
            rows = answer.json()["rows"]
            print(
                f"compare {name}: p50 {p50_ms(times):.0f} ms over {RUNS} runs, {len(rows)} rows, first "
                f"{rows[0]['label']} settling at {rows[0]['settling_time_s']:.4f} s"
            )


def duration_search() -> None:
    family = FAMILIES["pseudo_polynomial"]
    problem = CompareIn.model_validate(EXAMPLES["incerti_rest_to_rest"]["value"]).to_problem(Settings())
    family.warm_up(problem.solver)
    searched = family.default_options(problem)
    fixed = PseudoPolynomialOptions(duration_s=searched.duration_s)
    family.design(problem, searched)
    figures = {}
    for label, options in (("one fixed-duration solve", fixed), ("minimize_duration", searched)):
        times = []
        for _ in range(RUNS):
            start = time.perf_counter()
            design = family.design(problem, options)
            times.append(time.perf_counter() - start)
        figures[label] = p50_ms(times)
        solves = design.solver.solves if design.solver else 0
        print(f"pseudo-polynomial {label}: p50 {figures[label]:.1f} ms ({solves} solves)")
    ratio = figures["minimize_duration"] / figures["one fixed-duration solve"]
    print(f"minimize_duration / one solve: {ratio:.1f}x")


if __name__ == "__main__":
    duration_search()
    compare_examples()
