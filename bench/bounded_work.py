"""Bounded work per request (issue 23): issue 23's reproducers against a real server, with the resident set of
every process of the server sampled every 50 ms.

A real ``vibfree serve`` (``--processes`` HTTP processes x ``--workers`` solver workers, default 2 x 2; its stderr
in the system's temporary directory) gets, one after the other on fresh connections:

- ``reproducer``: ``POST /v1/profiles/input-shaped`` on a 330 Hz shaft (J_M 0.001, J_L 0.01, k 43000), 100 rad/s
  within 0.1 N m: before this work 103 -> 1133 MiB in the HTTP process for 8 s (the torque check sampled 2000
  points per period of an 11 s ramp);
- ``stiff x1000``: the same with k x 1000 (10.4 kHz), which needed tens of GB before;
- ``compare, large torque``: ``POST /v1/compare`` on the 1000 times stiffer shaft within 1000 N m (every family;
  time-optimal's linear programmes run in a solver worker);
- ``identify, 40k columns`` / ``1M columns`` / ``50 MB record``: ``POST /v1/identify`` text/csv records whose header
  check took 36 s (349 kB) and hours (4 MB) before, and a record above the 32 MiB body cap (a 413).

A thread samples psutil's RSS of the server's whole process tree (uvicorn's supervisor, its HTTP processes,
their solver workers, multiprocessing's resource tracker) every 50 ms from before the first request to after
the last, and the script prints each request's status, time and the field a 4xx names, the peak RSS of every
process over each request and over the run, and whether the acceptance holds: each answered within 1 s with a
200 or a 4xx naming a field, and every process under 400 MiB throughout. Not part of the test suite (a real
server, timings); a missed target is printed, the exit status stays 0 (make bench runs every benchmark):

    python bench/bounded_work.py
    python bench/bounded_work.py --processes 1 --workers 1
"""

from __future__ import annotations

import argparse
import contextlib
import http.client
import json
import sys
import threading
import time
from pathlib import Path
from typing import Any

import psutil

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.app.server import serving  # noqa: E402

SAMPLE_S = 0.05
BOUND_MIB = 400.0
ANSWER_S = 1.0
PLANT = {"kind": "two_inertia", "load_inertia_kgm2": 0.01, "motor_inertia_kgm2": 0.001, "stiffness_nm_per_rad": 43000}
STIFF = {**PLANT, "stiffness_nm_per_rad": 43000 * 1000}
REQUESTS: list[tuple[str, str, dict[str, Any]]] = [
    (
        "reproducer",
        "/v1/profiles/input-shaped",
        {"plant": PLANT, "target_velocity": 100, "limits": {"max_torque_nm": 0.1}},
    ),
    (
        "stiff x1000",
        "/v1/profiles/input-shaped",
        {"plant": STIFF, "target_velocity": 100, "limits": {"max_torque_nm": 0.1}},
    ),
    (
        "compare, large torque",
        "/v1/compare",
        {"plant": STIFF, "target_velocity": 100, "limits": {"max_torque_nm": 1000.0}},
    ),
]


def csv_record(columns: int, rows: int = 2, pad_to_bytes: int = 0) -> bytes:
    """A text/csv record for ``POST /v1/identify``: a time column and ``columns`` signals (``rows`` rows of zeros),
    padded with comment-free rows to at least ``pad_to_bytes``."""
    header = "time_s," + ",".join(f"s{i}" for i in range(columns))
    row = ",".join(["0"] * (columns + 1))
    body = "\n".join([header, *[row] * rows]) + "\n"
    if pad_to_bytes > len(body):
        line = "0," + "0\n"
        body += line * ((pad_to_bytes - len(body)) // len(line) + 1)
    return body.encode()


# Issue 23's CSV reproducers: the header check counted each name against all others (40k columns, 349 kB: 36 s;
# 1M columns, 4 MB: hours), and the 50 MB record of its acceptance (above the 32 MiB body cap: a 413).
CSV_REQUESTS: list[tuple[str, bytes]] = [
    ("identify, 40k columns", csv_record(40_000)),
    ("identify, 1M columns", csv_record(1_000_000, rows=0)),
    ("identify, 50 MB record", csv_record(1, pad_to_bytes=50 * 10**6)),
]


def server_root(port: int) -> psutil.Process:
    """The server's top process: from the one listening on ``port`` up through its parents while they are the
    server's (uvicorn's supervisor shares the socket with its HTTP processes; ``vibfree serve`` may sit above)."""
    pids = [
        c.pid
        for c in psutil.net_connections("tcp")
        if c.status == psutil.CONN_LISTEN and c.laddr and c.laddr.port == port and c.pid
    ]
    if not pids:
        raise RuntimeError(f"nothing listens on port {port}")
    process = psutil.Process(pids[0])
    with contextlib.suppress(psutil.NoSuchProcess):
        while (parent := process.parent()) is not None and any(
            word in " ".join(parent.cmdline()) for word in ("uvicorn", "vibfree")
        ):
            process = parent
    return process


def role(process: psutil.Process, root: psutil.Process) -> str:
    """What a process of the tree is: uvicorn's supervisor (the root), multiprocessing's resource tracker, an HTTP
    process (the supervisor's other children) or a solver worker (an HTTP process's children)."""
    try:
        command = " ".join(process.cmdline())
        parent = process.ppid()
    except psutil.NoSuchProcess:
        return "gone"
    if process.pid == root.pid:
        return "supervisor"
    if "resource_tracker" in command:
        return "resource tracker"
    if parent == root.pid:
        return "http"
    return "solver worker"


class Sampler(threading.Thread):
    """RSS of every process of the tree every SAMPLE_S: the peak per pid over the run and over each window."""

    def __init__(self, root: psutil.Process) -> None:
        super().__init__(daemon=True)
        self.root = root
        self.stop = threading.Event()
        self.roles: dict[int, str] = {}
        self.peak: dict[int, float] = {}
        self.window: dict[int, float] = {}
        self.samples = 0
        self.lock = threading.Lock()

    def run(self) -> None:
        while not self.stop.is_set():
            with contextlib.suppress(psutil.NoSuchProcess):
                tree = [self.root, *self.root.children(recursive=True)]
            for process in tree:
                try:
                    rss = process.memory_info().rss / 2**20
                except psutil.NoSuchProcess:
                    continue
                with self.lock:
                    if process.pid not in self.roles:
                        self.roles[process.pid] = role(process, self.root)
                    self.peak[process.pid] = max(self.peak.get(process.pid, 0.0), rss)
                    self.window[process.pid] = max(self.window.get(process.pid, 0.0), rss)
            self.samples += 1
            self.stop.wait(SAMPLE_S)

    def take_window(self) -> dict[int, float]:
        with self.lock:
            window, self.window = self.window, {}
        return window


def post(port: int, path: str, body: dict[str, Any] | bytes, timeout_s: float = 300.0) -> tuple[int, float, str, bool]:
    """One POST on a fresh connection (JSON, or ``bytes`` as text/csv): status, seconds, a note (the field a problem
    names, or its type; the answer's gist) and whether a problem names a field."""
    csv = isinstance(body, bytes)
    payload = body if isinstance(body, bytes) else json.dumps(body).encode()
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout_s)
    started = time.perf_counter()
    try:
        connection.request("POST", path, payload, {"content-type": "text/csv" if csv else "application/json"})
        response = connection.getresponse()
        data = response.read()
        elapsed = time.perf_counter() - started
    finally:
        connection.close()
    note, named = "", False
    if response.status >= 400:
        with contextlib.suppress(ValueError):
            problem = json.loads(data)
            named = bool(problem.get("field")) or response.status == 413  # a 413 names the body, by its status
            note = problem.get("field") or problem.get("type", "")
            note = f"{note}: {problem.get('detail', '')}"[:60]
    elif path == "/v1/compare":
        answer = json.loads(data)
        note = f"{len(answer['rows'])} rows, {len(answer['unavailable'])} unavailable"
    else:
        answer = json.loads(data)
        note = f"peak torque {answer['metrics']['peak_motor_torque_nm']:.6g} N m"
    return response.status, elapsed, note, named


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    env = {"VIBFREE_WORKERS": str(args.workers)}
    with serving(args.processes, env=env) as port:
        root = server_root(port)
        sampler = Sampler(root)
        sampler.start()
        time.sleep(0.5)
        idle = sampler.take_window()
        results = []
        requests: list[tuple[str, str, dict[str, Any] | bytes]] = [
            *REQUESTS,
            *[(name, "/v1/identify", record) for name, record in CSV_REQUESTS],
        ]
        for name, path, body in requests:
            status, elapsed, note, named = post(port, path, body)
            time.sleep(0.2)  # a few samples after the answer
            results.append((name, status, elapsed, note, named, sampler.take_window()))
        sampler.stop.set()
        sampler.join()
    every = f"RSS every {SAMPLE_S * 1000:.0f} ms"
    print(f"server: {args.processes} HTTP processes x {args.workers} solver workers; {every}")
    print(f"{sampler.samples} samples; idle before the requests: " + ", ".join(f"{v:.0f}" for v in idle.values()))
    pids = sorted(sampler.peak, key=lambda p: (sampler.roles[p], p))
    print(f"\n{'request':<24} {'status':>6} {'time s':>8}  {'answer':<60} peak RSS per process (MiB)")
    for name, status, elapsed, note, _, window in results:
        peaks = ", ".join(f"{sampler.roles[p]} {window[p]:.0f}" for p in pids if p in window)
        print(f"{name:<24} {status:>6} {elapsed:>8.3f}  {note:<60} {peaks}")
    print("\npeak RSS over the run:")
    for pid in pids:
        print(f"  {sampler.roles[pid]:<18} pid {pid:<8} {sampler.peak[pid]:7.1f} MiB")
    answered = all(
        elapsed < ANSWER_S and (status == 200 or (400 <= status < 500 and named))
        for _, status, elapsed, _, named, _ in results
    )
    bounded = all(v < BOUND_MIB for v in sampler.peak.values())
    print(f"\nacceptance: each answered within {ANSWER_S:g} s with a 200 or a 4xx naming a field: {answered}")
    print(f"acceptance: every process under {BOUND_MIB:g} MiB throughout: {bounded}")
    if not (answered and bounded):
        print("MISSED: see the figures above")


if __name__ == "__main__":
    main()
