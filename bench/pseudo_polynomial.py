"""Benchmark: pseudo-polynomial design on Incerti's Table III case.

Figures for docs/benchmarks.md: the one-off build of the CasADi problem, the median design time once it is
built (target: under 20 ms), and designs per second through the HTTP endpoint (uvicorn started
here with the default worker pool, requests from 4 client threads).
"""

from __future__ import annotations

import math
import os
import socket
import statistics
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx2 as httpx  # the test client library (a test dependency)

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from app.examples import INCERTI_TABLE_III  # noqa: E402
from models.plants import example_plants  # noqa: E402
from optim.families import pseudo_polynomial as pp  # noqa: E402

REQUEST = {"plant": INCERTI_TABLE_III, "displacement": 30 * math.pi, "duration_s": 1.0}


def core() -> None:
    start = time.perf_counter()
    pp.warm_up()
    build_s = time.perf_counter() - start
    request = pp.PseudoPolynomialRequest(example_plants()["incerti_table_iii"], 30 * math.pi, 1.0)
    times = []
    for _ in range(50):
        start = time.perf_counter()
        design = pp.design(request)
        times.append(time.perf_counter() - start)
    print(
        "build of the warm-up problems: orders 2-4 for each second-order plant kind (one-off, per worker): "
        f"{1e3 * build_s:.0f} ms"
    )
    print(
        f"design, problem built, median of 50: {1e3 * statistics.median(times):.2f} ms "
        f"(IPOPT {design.solver.iterations} iterations, energy ratio {design.energy_ratio:.1e})"
    )


def http(requests: int = 200, clients: int = 4) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = subprocess.Popen(
        [sys.executable, "-m", "uvicorn", "app.main:app", "--port", str(port), "--log-level", "warning"],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    try:
        base = f"http://127.0.0.1:{port}"
        with httpx.Client(base_url=base, timeout=60) as client:
            for _ in range(600):
                try:
                    if client.get("/readyz").status_code == 200:
                        break
                except httpx.TransportError:
                    pass
                time.sleep(0.1)
            client.post("/v1/profiles/pseudo-polynomial", json=REQUEST).raise_for_status()

            def one(_: int) -> float:
                start = time.perf_counter()
                client.post("/v1/profiles/pseudo-polynomial", json=REQUEST).raise_for_status()
                return time.perf_counter() - start

            start = time.perf_counter()
            with ThreadPoolExecutor(clients) as pool:
                latencies = list(pool.map(one, range(requests)))
            elapsed = time.perf_counter() - start
        print(
            f"HTTP, {requests} requests from {clients} clients: {requests / elapsed:.1f} designs/s, "
            f"median latency {1e3 * statistics.median(latencies):.0f} ms (2001-sample profile, load response, metrics)"
        )
    finally:
        server.terminate()
        server.wait(10)


if __name__ == "__main__":
    core()
    http()
