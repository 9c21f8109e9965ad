"""Benchmark (issue 23): the same requests answered idle and under load must be the same answers.

A real server (``vibfree serve`` in a subprocess, its default settings: tests/app/server.py) answers, one request
at a time: the README's robust time-optimal example with the band of issue 23 (frequency ratios 0.7-1.3), the
README's trade-off example and ``--count`` seeded random time-optimal requests (``random_requests``); first idle,
then while ``--clients`` threads loop on slow solves (the same robust band request, ~3-5 s of solving each; a
refused one waits 1 s). Each pair of bodies is compared without its wall times (every ``solve_time_s`` field);
the counts of identical and different answers are printed, with the fields that differ. A 504 (a solve past its
wall-clock last resort) under load is an honest answer, but it is counted apart from the identical ones.

    python bench/determinism.py [--count 50] [--clients 8] [--root CHECKOUT]

``--root`` serves another checkout (e.g. ``git archive 9e239dc | tar -x -C /tmp/old``: main before issue 23).
Not run by the test suite; it takes several minutes (the loaded pass is the slow one).
"""

from __future__ import annotations

import argparse
import http.client
import json
import os
import random
import sys
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.app.server import serving  # noqa: E402

PATH = "/v1/profiles/time-optimal"
_40HZ = {"plant": {"kind": "mode", "natural_frequency_hz": 40}, "displacement": 0.12}
_LIMITS = {"max_velocity": 5, "max_acceleration": 10}
ROBUST_BAND = {**_40HZ, "limits": _LIMITS, "robustness": {"frequency_ratio_range": [0.7, 1.3]}}
TRADEOFF = {
    **_40HZ,
    "limits": _LIMITS,
    "robustness": {"frequency_ratio_range": [0.9, 1.1]},
    "tradeoff": [0, 0.05, 0.1],
}
TIMING_FIELDS = {"solve_time_s"}  # the only wall times an answer reports


def random_requests(count: int, seed: int = 23) -> list[dict[str, Any]]:
    """Single-mode time-optimal requests: 2-40 Hz, damping 0-0.1, moves 0.02-1, limits of everyday axes; a quarter
    jerk-limited, 40 % with a band of +-3-20 %, 15 % with derivative_order 1 (the rest zero residual); a fifth start
    and end in motion (velocities within +-80 % of max_velocity, drawn from a second generator so that the other
    draws are those of the runs before issue 25's initial_state)."""
    rng = random.Random(seed)
    motion = random.Random(seed + 25)
    out = []
    for _ in range(count):
        plant = {
            "kind": "mode",
            "natural_frequency_hz": round(rng.uniform(2.0, 40.0), 3),
            "damping_ratio": rng.choice([0.0, 0.01, 0.05, 0.1]),
        }
        displacement = round(10 ** rng.uniform(-1.7, 0.0), 4)
        limits = {"max_velocity": round(rng.uniform(0.2, 5.0), 3), "max_acceleration": round(rng.uniform(2.0, 30.0), 3)}
        request: dict[str, Any] = {"plant": plant, "displacement": displacement, "limits": limits}
        if rng.random() < 0.25:
            limits["max_jerk"] = round(rng.uniform(100.0, 2000.0), 1)
        kind = rng.random()
        if kind < 0.4:
            h = round(rng.uniform(0.03, 0.2), 3)
            request["robustness"] = {"frequency_ratio_range": [1 - h, 1 + h]}
        elif kind < 0.55:
            request["robustness"] = {"derivative_order": 1}
        if motion.random() < 0.2:
            top = 0.8 * limits["max_velocity"]
            request["initial_state"] = {"velocity": round(motion.uniform(-top, top), 3)}
            request["final_state"] = {"velocity": round(motion.uniform(-top, top), 3)}
        out.append(request)
    return out


def post(port: int, payload: dict[str, Any], timeout_s: float = 600.0) -> tuple[int, bytes]:
    """One POST on a fresh connection (so that either HTTP process may take it)."""
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout_s)
    try:
        connection.request("POST", PATH, body=json.dumps(payload), headers={"content-type": "application/json"})
        response = connection.getresponse()
        return response.status, response.read()
    finally:
        connection.close()


def without_timing(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: without_timing(v) for k, v in value.items() if k not in TIMING_FIELDS}
    if isinstance(value, list):
        return [without_timing(v) for v in value]
    return value


def differences(a: Any, b: Any, path: str = "") -> list[str]:
    """The paths where two JSON values differ (arrays as one path)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for key in sorted(set(a) | set(b)):
            out += differences(a.get(key), b.get(key), f"{path}.{key}" if path else key)
        return out
    return [] if a == b else [path or "(body)"]


def answers(port: int, requests: list[tuple[str, dict[str, Any]]]) -> list[tuple[int, Any, float]]:
    out = []
    for _, payload in requests:
        started = time.perf_counter()
        status, body = post(port, payload)
        out.append((status, without_timing(json.loads(body)), time.perf_counter() - started))
    return out


def loading(port: int, clients: int, stop: threading.Event, statuses: Counter[int]) -> list[threading.Thread]:
    def loop() -> None:
        while not stop.is_set():
            try:
                status, _ = post(port, ROBUST_BAND, timeout_s=300.0)
            except OSError:
                status = -1
            statuses[status] += 1
            if status == 503:
                stop.wait(1.0)

    threads = [threading.Thread(target=loop, daemon=True) for _ in range(clients)]
    for thread in threads:
        thread.start()
    return threads


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--count", type=int, default=50, help="random requests")
    parser.add_argument("--seed", type=int, default=23)
    parser.add_argument("--clients", type=int, default=8, help="clients sending slow solves in the loaded pass")
    parser.add_argument("--root", type=Path, default=ROOT, help="the checkout to serve")
    args = parser.parse_args()
    requests = [("robust band 0.7-1.3", ROBUST_BAND), ("README trade-off", TRADEOFF)]
    requests += [(f"random {k}", r) for k, r in enumerate(random_requests(args.count, args.seed))]
    print(f"cores {len(os.sched_getaffinity(0))}; serving {args.root}; {len(requests)} requests")
    with serving(None, root=args.root) as port:
        print(f"load average {os.getloadavg()}")
        started = time.perf_counter()
        idle = answers(port, requests)
        print(f"idle: {len(idle)} answers in {time.perf_counter() - started:.0f} s, {Counter(s for s, _, _ in idle)}")
        stop, statuses = threading.Event(), Counter[int]()
        threads = loading(port, args.clients, stop, statuses)
        time.sleep(5.0)  # the pool saturated before the first measured request
        started = time.perf_counter()
        try:
            loaded = answers(port, requests)
        finally:
            stop.set()
        elapsed = time.perf_counter() - started
        for thread in threads:
            thread.join(timeout=300.0)
        print(
            f"loaded ({args.clients} clients looping on the robust band request, their answers {dict(statuses)}): "
            f"{len(loaded)} answers in {elapsed:.0f} s, {Counter(s for s, _, _ in loaded)}; "
            f"load average {os.getloadavg()}"
        )
    same = different = timed_out = 0
    for (name, _), (s1, b1, t1), (s2, b2, t2) in zip(requests, idle, loaded, strict=True):
        if s1 == s2 and b1 == b2:
            same += 1
            continue
        if s2 == 504 and s1 != 504:
            timed_out += 1
            print(f"  {name}: {s1} idle, 504 loaded ({t2:.1f} s)")
            continue
        different += 1
        paths = differences(b1, b2) if s1 == s2 else ["status"]
        print(f"  {name}: {s1} idle ({t1:.1f} s), {s2} loaded ({t2:.1f} s); differ: {', '.join(paths[:8])}")
        if name.startswith("robust band") and s1 == s2 == 200:
            grids = [b["design"]["grid"] for b in (b1, b2)]
            print(f"    grid steps {grids[0]['steps']} idle, {grids[1]['steps']} loaded")
    print(
        f"\nidentical: {same} of {len(requests)}; different: {different}; 504 under load only: {timed_out} "
        f"(bodies compared without {', '.join(sorted(TIMING_FIELDS))})"
    )
    first = [b for s, b, _ in (idle[0], loaded[0]) if s == 200]
    print("robust band 0.7-1.3: " + ", ".join(f"{b['design']['grid']['steps']} steps" for b in first))


if __name__ == "__main__":
    main()
