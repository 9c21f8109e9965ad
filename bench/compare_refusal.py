"""Benchmark: how fast POST /v1/compare is refused when the solver pool has no room for it (issue 23).

Issue 23's target: with every solver worker busy and the queue full of slow solves, a compare (which needs
room for all its solver runs at once) is refused with a 503 ``busy`` and a Retry-After in well under 100 ms
(p99 < 100 ms), and none of its designs runs; before, it waited 12-43 s for the families it was admitted for,
then answered 503.

A real server (``vibfree serve``, tests/app/server.py) runs one HTTP process, so that one pool is saturated,
with its default solver workers and queue (``Settings``: 2 workers, 4 queued solves per worker). A load
process keeps ``CLIENTS`` threads (twice the places: running plus queued) looping on the slow solve of
bench/health_under_load.py (the robust time-optimal example, ~1.5 s of solving); a refused load client
retries after 0.1 s, so the freed places fill again at once. Then ``--requests`` compare requests of the
Incerti Table III example (three solver runs: time-optimal, pseudo-polynomial, STAP optimized) are sent one
after the other, each on a fresh connection, and timed from the request to the last byte of the answer.

Printed: the statuses, p50 / p99 / max latency of the refusals, how many carried Retry-After, and the designs
of the families the load does not run (every family but the time-optimal one) counted by the server's
/metrics over the compare requests: 0 when no part of a refused compare ran. ``--root`` serves another
checkout (e.g. the main before this work, ``git archive <commit> | tar -x -C /tmp/old``) for the figures
before; ``--requests 5`` there, since each old compare waits for its queued solves.

    python bench/compare_refusal.py [--requests 200] [--root PATH] [--load-s 3]
"""

from __future__ import annotations

import argparse
import http.client
import json
import multiprocessing
import statistics
import sys
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.health_under_load import SLOW_SOLVE  # noqa: E402
from tests.app.server import scrape, serving  # noqa: E402

TARGET_P99_MS = 100.0
WORKERS = 2  # the settings' default on 2 cores (app.settings._default_workers)
QUEUED = 4 * WORKERS  # Settings.queue_limit for one process
CLIENTS = 2 * (WORKERS + QUEUED)
RETRY_S = 0.1
INCERTI = {
    "plant": {
        "kind": "belt_platform",
        "platform_inertia_kgm2": 6,
        "branch_stiffness_n_per_m": 90000,
        "branch_damping_ns_per_m": 150,
        "motor_pulley_radius_m": 0.06,
        "platform_pulley_radius_m": 0.18,
        "gear_ratio": 0.1,
    },
    "displacement": 94.24777960769379,
    "limits": {"max_velocity": 200.0, "max_acceleration": 700.0},
}


def post(port: int, path: str, payload: dict[str, Any], timeout_s: float = 300.0) -> tuple[int, dict[str, str]]:
    """One POST on a fresh connection: the status and the headers (lower-case names), the body read."""
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout_s)
    try:
        connection.request("POST", path, json.dumps(payload), {"content-type": "application/json"})
        response = connection.getresponse()
        response.read()
        return response.status, {k.lower(): v for k, v in response.getheaders()}
    finally:
        connection.close()


def load(port: int, stop: Any, started: Any, statuses: Any) -> None:
    """The slow solves, in a process of their own: ``CLIENTS`` threads until ``stop`` is set."""
    counts: Counter[int] = Counter()
    lock = threading.Lock()

    def client() -> None:
        while not stop.is_set():
            status, _ = post(port, "/v1/profiles/time-optimal", SLOW_SOLVE)
            with lock:
                counts[status] += 1
            if status == 503:
                time.sleep(RETRY_S)

    threads = [threading.Thread(target=client) for _ in range(CLIENTS)]
    for thread in threads:
        thread.start()
    started.set()
    for thread in threads:
        thread.join()
    statuses.update(counts)


def percentile(samples: list[float], q: float) -> float:
    ordered = sorted(samples)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def designs(port: int) -> float:
    """Designs the service layer ran of the families the load does not use (vibfree_solves_total)."""
    return sum(
        value
        for (name, labels), value in scrape(port).items()
        if name == "vibfree_solves_total" and dict(labels).get("family") != "time_optimal"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--requests", type=int, default=200, help="compare requests (default 200: a p99 is not the max)"
    )
    parser.add_argument("--root", type=Path, default=ROOT, help="the checkout to serve (default: this one)")
    parser.add_argument("--load-s", type=float, default=3.0, help="load before the first compare (fills the queue)")
    args = parser.parse_args()
    env = {"VIBFREE_WORKERS": str(WORKERS), "VIBFREE_MAX_QUEUED": str(QUEUED)}
    context = multiprocessing.get_context("spawn")
    with serving(1, root=args.root, env=env) as port:
        post(port, "/v1/profiles/time-optimal", SLOW_SOLVE)  # one warm call
        manager = context.Manager()
        stop, started, load_statuses = manager.Event(), manager.Event(), manager.dict()
        generator = context.Process(target=load, args=(port, stop, started, load_statuses))
        generator.start()
        started.wait(60)
        time.sleep(args.load_s)
        before = designs(port)
        latencies: dict[int, list[float]] = {}
        retry_after = 0
        for _ in range(args.requests):
            start = time.perf_counter()
            status, headers = post(port, "/v1/compare", INCERTI)
            latencies.setdefault(status, []).append(1e3 * (time.perf_counter() - start))
            retry_after += status == 503 and headers.get("retry-after", "").isdigit()
        ran = designs(port) - before
        stop.set()
        generator.join(300)
        load_counts = dict(load_statuses)
    refused = latencies.get(503, [])
    print(
        f"server: 1 HTTP process, {WORKERS} solver workers, {QUEUED} queued solves; load: {CLIENTS} clients on the "
        f"slow solve (statuses {load_counts}); root {args.root}"
    )
    print(f"compare requests: {args.requests}, by status: { {s: len(v) for s, v in sorted(latencies.items())} }")
    failures = []
    if refused:
        print(
            f"refusals (503): first {refused[0]:.1f} ms, slowest after it {max(refused[1:], default=0.0):.1f} ms; "
            f"p50 {statistics.median(refused):.1f} ms, p99 {percentile(refused, 0.99):.1f} ms, "
            f"max {max(refused):.1f} ms; with Retry-After: {retry_after} of {len(refused)}"
        )
        if percentile(refused, 0.99) >= TARGET_P99_MS:
            failures.append(f"refusal p99 {percentile(refused, 0.99):.1f} ms >= {TARGET_P99_MS:g} ms")
        if retry_after != len(refused):
            failures.append("a 503 without Retry-After")
    for status, samples in sorted(latencies.items()):
        if status != 503:
            print(f"answered {status}: p50 {statistics.median(samples):.0f} ms, max {max(samples):.0f} ms")
    print(f"designs of the compared families run meanwhile (0: nothing of a refused compare ran): {ran:g}")
    for failure in failures:
        print("MISSED", failure)
    return 0


if __name__ == "__main__":
    sys.exit(main())
