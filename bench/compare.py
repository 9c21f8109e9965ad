"""Benchmark: /v1/compare on its OpenAPI examples, and the pseudo-polynomial duration search it runs.

Figures for docs/benchmarks.md (issue 11's target: compare answers its examples in at most 1 s p50 on the
2-core development machine). Compare is timed through the app with its solver pool (in-process
client, so the figure is the service's work, not the loopback's); the duration search it runs for the
pseudo-polynomial row by bench/pseudo_polynomial_duration.py, as a ratio to one fixed-duration design.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from fastapi.testclient import TestClient  # noqa: E402

from app.examples.compare import EXAMPLES  # noqa: E402
from app.main import app  # noqa: E402

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


if __name__ == "__main__":
    import pseudo_polynomial_duration  # bench/ is on sys.path when run as a script

    pseudo_polynomial_duration.main()
    compare_examples()
