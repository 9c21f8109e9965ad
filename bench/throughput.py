"""Throughput of the STAP and pseudo-polynomial examples at 1, 4 and 8 concurrent clients, against several
servers in one run (issue 15 acceptance: the default >= 1.8x the single-process figure at 8 clients, and no
fall from 4 to 8 clients), and the first request after readiness against the second (warm-ups).

Servers (``--configs``, each a real ``vibfree serve`` in a subprocess, stopped after its measurements):

- ``old``: ``--old-root`` (the main before this work, e.g. ``git worktree add /tmp/wt-cores-old e89cdee``),
  one uvicorn process (asyncio loop, h11) with its default pool;
- ``p1``: this checkout with ``VIBFREE_PROCESSES=1`` (its default workers: 2 on 2 cores);
- ``default``: this checkout's defaults (one process per core, workers per process = cores / processes);
- ``p2w2``: 2 processes with 2 solver workers each (4 solver processes on 2 cores: oversubscribed).

The clients are one asyncio process writing prebuilt HTTP/1.1 requests on keep-alive connections (each
connection is reopened after ``RECONNECT_EVERY`` requests so the kernel spreads them over the server's
processes): cheap beside the server, and its own CPU time is printed. Every answer must be a 200.
The machine may be shared: the load average is printed with each server.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import resource
import sys
import time
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.app.server import serving  # noqa: E402

RECONNECT_EVERY = 50
CONCURRENCY = (1, 4, 8)

# The README's curl example (Incerti Table III) and the STAP route's first example (Cusimano Sec. 3, closed form).
PSEUDO_POLYNOMIAL = {
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
    "duration_s": 1.0,
}

from app.examples.stap import EXAMPLES as STAP_EXAMPLES  # noqa: E402

STAP = STAP_EXAMPLES["section_3_k1"]["value"]
LOADS = {
    "stap": ("/v1/profiles/stap", STAP),
    "pseudo_polynomial": ("/v1/profiles/pseudo-polynomial", PSEUDO_POLYNOMIAL),
}


def _cold_requests() -> dict[str, tuple[str, dict]]:
    """The examples whose problems have active limits (the issue's cold requests), from the routes' own."""
    from app.examples import pseudo_polynomial, stap

    return {
        "pp shortest_with_limits": (
            "/v1/profiles/pseudo-polynomial",
            pseudo_polynomial.EXAMPLES["shortest_with_limits"]["value"],
        ),
        "stap table_2_torque_limit": ("/v1/profiles/stap", stap.EXAMPLES["table_2_torque_limit"]["value"]),
        "stap robust_optimized": ("/v1/profiles/stap", stap.EXAMPLES["robust_optimized"]["value"]),
    }


def request_bytes(path: str, payload: dict) -> bytes:
    body = json.dumps(payload).encode()
    head = (
        f"POST {path} HTTP/1.1\r\nhost: 127.0.0.1\r\ncontent-type: application/json\r\n"
        f"content-length: {len(body)}\r\n\r\n"
    )
    return head.encode() + body


async def _read_response(reader: asyncio.StreamReader) -> int:
    head = await reader.readuntil(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    status = int(lines[0].split()[1])
    length = next(int(line.split(":", 1)[1]) for line in lines if line.lower().startswith("content-length:"))
    await reader.readexactly(length)
    return status


async def _client(port: int, request: bytes, stop_at: float, counts: list[int], errors: list[int]) -> None:
    while time.perf_counter() < stop_at:
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        try:
            for _ in range(RECONNECT_EVERY):
                if time.perf_counter() >= stop_at:
                    break
                writer.write(request)
                status = await _read_response(reader)
                (counts if status == 200 else errors).append(status)
        finally:
            writer.close()


async def _load(port: int, request: bytes, clients: int, seconds: float) -> tuple[int, int]:
    counts: list[int] = []
    errors: list[int] = []
    stop_at = time.perf_counter() + seconds
    await asyncio.gather(*(_client(port, request, stop_at, counts, errors) for _ in range(clients)))
    return len(counts), len(errors)


async def _one(port: int, request: bytes) -> tuple[int, float]:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        started = time.perf_counter()
        writer.write(request)
        status = await _read_response(reader)
        return status, time.perf_counter() - started
    finally:
        writer.close()


def _cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _tree_cpu_s(root_pid: int) -> float:
    total = 0.0
    try:
        root = psutil.Process(root_pid)
        for p in [root, *root.children(recursive=True)]:
            try:
                t = p.cpu_times()
                total += t.user + t.system
            except psutil.NoSuchProcess:
                pass
    except psutil.NoSuchProcess:
        pass
    return total


def _server_pid(port: int) -> int | None:
    """The server's top process: from a process listening on ``port``, up through its parents while they run
    uvicorn (its supervisor shares the socket with its HTTP processes, which are spawned children)."""
    pids = [
        c.pid
        for c in psutil.net_connections("tcp")
        if c.status == psutil.CONN_LISTEN and c.laddr and c.laddr.port == port and c.pid
    ]
    if not pids:
        return None
    process = psutil.Process(pids[0])
    with contextlib.suppress(psutil.NoSuchProcess):
        while (parent := process.parent()) is not None and "uvicorn" in " ".join(parent.cmdline()):
            process = parent
    return process.pid


def measure(label: str, root: Path, processes: int | None, env: dict[str, str], seconds: float) -> dict:
    out: dict = {"label": label, "load_before": os.getloadavg()}
    # The old main ran on asyncio's loop (uvloop was not installed then; under uvloop its pool breaks on large
    # answers, fixed in runtime.pool): plain uvicorn --loop asyncio with its serve flags.
    extra = ("--http", "h11", "--timeout-keep-alive", "5", "--loop", "asyncio") if processes == 0 else ()
    with serving(processes, root=root, env=env, extra=extra) as port:
        pid = _server_pid(port)
        cold = {}
        for name, (path, payload) in _cold_requests().items():
            request = request_bytes(path, payload)
            first = asyncio.run(_one(port, request))
            second = asyncio.run(_one(port, request))
            cold[name] = (first, second)
        out["cold"] = cold
        rates = {}
        for load, (path, payload) in LOADS.items():
            request = request_bytes(path, payload)
            asyncio.run(_load(port, request, 2, 1.0))  # warm the connections and the code paths
            for clients in CONCURRENCY:
                cpu0, server0, t0 = _cpu_s(), _tree_cpu_s(pid) if pid else 0.0, time.perf_counter()
                ok, bad = asyncio.run(_load(port, request, clients, seconds))
                elapsed = time.perf_counter() - t0
                rates[(load, clients)] = {
                    "rps": ok / elapsed,
                    "errors": bad,
                    "client_cpu": (_cpu_s() - cpu0) / elapsed,
                    "server_cpu": ((_tree_cpu_s(pid) - server0) / elapsed) if pid else float("nan"),
                }
        out["rates"] = rates
    out["load_after"] = os.getloadavg()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--old-root", type=Path, default=Path("/tmp/wt-cores-old"))
    parser.add_argument("--configs", default="old,p1,default,p2w2")
    parser.add_argument("--seconds", type=float, default=6.0, help="per load and concurrency")
    args = parser.parse_args()
    configs = {
        "old": (args.old_root, 0, {}),
        "p1": (ROOT, 1, {}),
        "default": (ROOT, None, {}),
        "p2w2": (ROOT, 2, {"VIBFREE_WORKERS": "2"}),
    }
    print(f"cores {len(os.sched_getaffinity(0))}; {args.seconds:g} s per point; client: one asyncio process")
    results = []
    for label in args.configs.split(","):
        root, processes, env = configs[label]
        if label == "old" and not (root / "app").is_dir():
            print(f"old: {root} missing (git worktree add {root} e89cdee); skipped")
            continue
        result = measure(label, root, processes, env, args.seconds)
        results.append(result)
        print(f"\n[{label}] load average {result['load_before']} -> {result['load_after']}")
        for name, ((s1, t1), (s2, t2)) in result["cold"].items():
            print(
                f"  first request {name}: {t1 * 1e3:8.1f} ms ({s1}), "
                f"second {t2 * 1e3:8.1f} ms ({s2}), ratio {t1 / t2:.2f}"
            )
        for (load, clients), r in result["rates"].items():
            print(
                f"  {load:18s} {clients} clients: {r['rps']:7.1f} req/s  errors {r['errors']}  "
                f"client CPU {100 * r['client_cpu']:4.0f} %  server CPU {100 * r['server_cpu']:4.0f} %"
            )
    by = {r["label"]: r["rates"] for r in results}
    print("\nratios at 8 clients (req/s over the single-process figure of this checkout, p1; and over old):")
    for load in LOADS:
        line = f"  {load:18s}"
        for label in by:
            rate = by[label][(load, 8)]["rps"]
            base = by.get("p1", by[label])[(load, 8)]["rps"]
            old = by.get("old", by[label])[(load, 8)]["rps"]
            four = by[label][(load, 4)]["rps"]
            line += f"  {label}: {rate / base:.2f}x p1, {rate / old:.2f}x old, 8/4 clients {rate / four:.2f}"
        print(line)


if __name__ == "__main__":
    main()
