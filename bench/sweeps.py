"""Benchmark: a design sweep of 50 plants answers in the time of its slowest design x points / workers.

Issue 15's target: ``POST /v1/sweeps`` of the README's 40 Hz time-optimal example over 50 natural frequencies
(30 to 50 Hz) answers within 1.5x of (slowest single design x 50 / workers), and the same sweep on a Dask
``LocalCluster`` (2 worker processes, one thread each) gives identical rows.

A real uvicorn serves the app on loopback with its default settings (its solver workers: 2 on this machine). The
reference is measured in the same run, on the same server: each of the 50 designs alone, one after the other, as
``POST /v1/profiles/time-optimal`` (the wall time a client sees); the slowest of them times 50 / workers is what a
perfectly parallel sweep would take. Then the sweep, read line by line as it streams. Then the server is stopped,
a LocalCluster started, and a second server with ``VIBFREE_DASK_SCHEDULER`` set to it runs the same sweep; its
rows must equal the pool's in every field but ``elapsed_s`` (timing). Everything started here is stopped here.

    python bench/sweeps.py [points]
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx2 as httpx
import orjson

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from app.settings import Settings  # noqa: E402  (bench/ scripts run from anywhere, like the others)
from vibfree.cli import SINGLE_THREADED_BLAS  # noqa: E402

# Dask's nanny starts its workers with one BLAS thread (distributed's nanny.pre-spawn-environ); the time-optimal
# design's last bits and IPOPT iteration counts depend on OpenBLAS' thread count, so the service's workers get the
# same environment here: with it the rows are bit-identical, without it they differ at round-off (1e-15 relative).
ONE_BLAS_THREAD = dict.fromkeys(SINGLE_THREADED_BLAS, "1")  # what vibfree serve and the image default to

BASE = {  # the README's 40 Hz time-optimal example
    "plant": {"kind": "mode", "natural_frequency_hz": 40.0, "damping_ratio": 0.0},
    "displacement": 0.12,
    "limits": {"max_velocity": 5.0, "max_acceleration": 10.0},
}
SENSITIVITY = {"min_ratio": 0.5, "max_ratio": 1.5, "count": 201}  # what the sweep gives each point
ACCEPTANCE = 1.5


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def server(env: dict[str, str] | None = None) -> Iterator[str]:
    port = free_port()
    command = [sys.executable, "-m", "uvicorn", "app.main:app", "--port", str(port), "--log-level", "warning"]
    process = subprocess.Popen(
        command,
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT), **ONE_BLAS_THREAD, **(env or {})},
        stdout=subprocess.DEVNULL,
    )
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 180
        while True:
            try:
                if httpx.get(base + "/readyz", timeout=2).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError("the service did not become ready")
            time.sleep(0.2)
        yield base
    finally:
        process.terminate()
        try:
            process.wait(15)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(5)


def frequencies(points: int) -> list[float]:
    return [30.0 + 20.0 * k / (points - 1) for k in range(points)]


def sweep(base: str, points: int) -> tuple[float, list[dict[str, Any]]]:
    body = {
        "family": "time-optimal",
        "request": BASE,
        "axes": [{"path": "plant.natural_frequency_hz", "values": frequencies(points)}],
    }
    started = time.perf_counter()
    lines = []
    with httpx.stream("POST", base + "/v1/sweeps", json=body, timeout=600) as response:
        response.raise_for_status()
        for raw in response.iter_lines():
            if raw:
                lines.append(orjson.loads(raw))
    return time.perf_counter() - started, lines


def single_designs(base: str, points: int) -> list[float]:
    times = []
    with httpx.Client(base_url=base, timeout=120) as http:
        for hz in frequencies(points):
            request = {**BASE, "plant": {**BASE["plant"], "natural_frequency_hz": hz}, "sensitivity": SENSITIVITY}
            started = time.perf_counter()
            http.post("/v1/profiles/time-optimal", json=request).raise_for_status()
            times.append(time.perf_counter() - started)
    return times


def rows(lines: list[dict[str, Any]]) -> list[dict[str, Any]]:
    out = sorted((x for x in lines if x["line"] == "row"), key=lambda r: r["index"])
    return [{k: v for k, v in r.items() if k != "elapsed_s"} for r in out]


def main() -> int:
    from distributed import LocalCluster

    points = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    workers = Settings().workers
    with server() as base:
        sweep(base, 4)  # both workers have run a design once
        singles = single_designs(base, points)
        wall_s, pool_lines = sweep(base, points)
    slowest = max(singles)
    reference = slowest * points / workers
    summary = pool_lines[-1]
    in_worker = max(r["elapsed_s"] for r in pool_lines if r["line"] == "row")
    print(f"{points} points, {workers} workers; failed {summary['failed']}")
    print(f"single designs over HTTP: slowest {slowest:.3f} s, median {sorted(singles)[len(singles) // 2]:.3f} s")
    print(f"slowest design in its worker (the rows' elapsed_s): {in_worker:.3f} s")
    print(f"sweep wall time {wall_s:.2f} s; reference slowest x points / workers = {reference:.2f} s")
    own = sum(r["elapsed_s"] for r in pool_lines if r["line"] == "row") / workers
    print(f"the sweep's own designs: sum of elapsed_s / workers = {own:.2f} s (wall / that = {wall_s / own:.2f})")
    ratio = wall_s / reference
    print(f"ratio sweep / reference = {ratio:.2f} (acceptance <= {ACCEPTANCE})")

    with (
        LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
        server({"VIBFREE_DASK_SCHEDULER": cluster.scheduler_address}) as dask_base,
    ):
        sweep(dask_base, 4)  # the Dask workers import and warm up
        dask_wall_s, dask_lines = sweep(dask_base, points)
    identical = rows(dask_lines) == rows(pool_lines)
    print(
        f"LocalCluster (2 processes x 1 thread): wall {dask_wall_s:.2f} s, ratio to the reference "
        f"{dask_wall_s / reference:.2f}; rows identical to the pool's: {identical}"
    )
    for a, b in zip(rows(pool_lines), rows(dask_lines), strict=True):
        differing = {k: (a[k], b.get(k)) for k in a if a[k] != b.get(k)}
        if differing:
            print(f"  point {a['index']} differs: {differing}")
    return 0 if ratio <= ACCEPTANCE and identical and summary["failed"] == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
