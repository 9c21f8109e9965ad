"""Benchmark: /healthz and /readyz latency while slow solves saturate the solver workers.

Issue 13's target: with every worker busy and the queue full, `/healthz` and `/readyz` answer with
p99 <= 50 ms, no request gets a 500, and every refusal is a 503 with Retry-After. The reference is the
same probes on the idle service, measured in the same run.

A real uvicorn serves the app on loopback (as `make serve` does) with its default settings (2 workers on
this machine, 4 queued solves per worker). ``CLIENTS`` threads (twice what the pool admits: running plus
queued) each loop on a slow solve, the robust time-optimal example of the README (~1.5 s of solving); a
refused client waits its Retry-After (at most 1 s, to keep the queue full) and tries again. The clients run
in a process of their own; a probe thread in this one polls both endpoints every 50 ms. A 504 (a solve over
its wall-time cap on a loaded machine) is an honest answer and is counted, not failed.

    python bench/health_under_load.py [seconds [clients]]
"""

from __future__ import annotations

import multiprocessing
import os
import socket
import statistics
import subprocess
import sys
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

import httpx2 as httpx

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from app.settings import Settings  # noqa: E402  (bench/ scripts run from anywhere, like the others)

SLOW_SOLVE = {
    "plant": {"kind": "mode", "natural_frequency_hz": 40},
    "displacement": 0.12,
    "limits": {"max_velocity": 5, "max_acceleration": 10},
    "robustness": {"frequency_ratio_range": [0.9, 1.1]},
}
PROBE_PERIOD_S = 0.05
TARGET_P99_MS = 50.0


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def percentile(samples: list[float], q: float) -> float:
    ordered = sorted(samples)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def probe(base: str, stop: threading.Event, out: dict[str, list[float]], statuses: Counter[str]) -> None:
    with httpx.Client(base_url=base, timeout=10) as http:
        while not stop.is_set():
            for path in ("/healthz", "/readyz"):
                start = time.perf_counter()
                response = http.get(path)
                out[path].append(1e3 * (time.perf_counter() - start))
                statuses[f"{path} {response.status_code}"] += 1
            time.sleep(PROBE_PERIOD_S)


def client(base: str, stop: threading.Event, statuses: Counter[str], problems: list[str]) -> None:
    with httpx.Client(base_url=base, timeout=120) as http:
        while not stop.is_set():
            response = http.post("/v1/profiles/time-optimal", json=SLOW_SOLVE)
            statuses[str(response.status_code)] += 1
            if response.status_code == 503:
                retry = response.headers.get("retry-after")
                if retry is None or response.headers.get("content-type") != "application/problem+json":
                    problems.append(f"503 without Retry-After or problem body: {response.headers}")
                time.sleep(min(1.0, float(retry or 1)))
            elif response.status_code >= 500 and response.status_code != 504:
                problems.append(f"{response.status_code}: {response.text[:300]}")


def load(base: str, clients: int, load_s: float, results: Any) -> None:
    """The load generator, in its own process so that its threads do not delay the probe's measurements."""
    statuses: Counter[str] = Counter()
    problems: list[str] = []
    stop = threading.Event()
    threads = [threading.Thread(target=client, args=(base, stop, statuses, problems)) for _ in range(clients)]
    for t in threads:
        t.start()
    time.sleep(load_s)
    stop.set()
    for t in threads:
        t.join()
    results.put((dict(statuses), problems))


def summary(name: str, samples: list[float]) -> str:
    return (
        f"{name}: p50 {statistics.median(samples):.1f} ms, p99 {percentile(samples, 0.99):.1f} ms, "
        f"max {max(samples):.1f} ms over {len(samples)} probes"
    )


def main(load_s: float = 30.0, clients: int | None = None) -> int:
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    server = subprocess.Popen(
        [sys.executable, "-m", "uvicorn", "app.main:app", "--port", str(port), "--no-access-log"],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    try:
        with httpx.Client(base_url=base, timeout=5) as http:
            deadline = time.monotonic() + 120
            while True:
                try:
                    ready = http.get("/readyz")
                    if ready.status_code == 200 and ready.json().get("ready", 0) == ready.json()["workers"]:
                        break
                except httpx.TransportError:
                    pass
                assert time.monotonic() < deadline, "the service did not become ready"
                time.sleep(0.2)
            stats = ready.json()
            http.post("/v1/profiles/time-optimal", json=SLOW_SOLVE)  # one warm call
        admitted = stats["workers"] + Settings().queue_limit  # the server reads the same environment
        clients = clients or 2 * admitted

        idle: dict[str, list[float]] = {"/healthz": [], "/readyz": []}
        probe_statuses: Counter[str] = Counter()
        stop = threading.Event()
        prober = threading.Thread(target=probe, args=(base, stop, idle, probe_statuses))
        prober.start()
        time.sleep(min(10.0, load_s / 3))
        stop.set()
        prober.join()

        loaded: dict[str, list[float]] = {"/healthz": [], "/readyz": []}
        context = multiprocessing.get_context("spawn")
        results = context.Queue()
        generator = context.Process(target=load, args=(base, clients, load_s + 2.0, results))
        generator.start()
        time.sleep(2.0)  # let the queue fill
        stop = threading.Event()
        prober = threading.Thread(target=probe, args=(base, stop, loaded, probe_statuses))
        prober.start()
        time.sleep(load_s)
        stop.set()
        prober.join()
        solve_statuses, problems = results.get(timeout=300)
        generator.join()
    finally:
        server.terminate()
        server.wait(30)

    print(f"workers {stats['workers']}, admitted (running + queued) {admitted}, clients {clients}, load {load_s:g} s")
    for path in ("/healthz", "/readyz"):
        print("idle   " + summary(path, idle[path]))
        print("loaded " + summary(path, loaded[path]))
        ratio = percentile(loaded[path], 0.99) / percentile(idle[path], 0.99)
        print(f"       {path} p99 loaded / idle: {ratio:.2f}")
    print(f"solve requests by status: {dict(solve_statuses)}; probes by status: {dict(probe_statuses)}")
    failures = list(problems)
    for path in ("/healthz", "/readyz"):
        if percentile(loaded[path], 0.99) > TARGET_P99_MS:
            failures.append(f"{path} p99 above {TARGET_P99_MS:g} ms")
    if any(k.endswith(("500", "503")) for k in probe_statuses):
        failures.append(f"a probe failed: {dict(probe_statuses)}")
    for failure in failures[:10]:
        print("FAIL", failure)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(*(float(a) if i == 0 else int(a) for i, a in enumerate(sys.argv[1:3]))))
