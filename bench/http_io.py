"""The HTTP I/O path of issue 15, against main (e89cdee) side by side in one run.

Two real uvicorn servers, started by this script (each in a subprocess, killed at the end, readiness awaited on
``/readyz``), one per checkout: this worktree (with its Makefile's SERVE_FLAGS) and main at ``OLD_COMMIT``
(checked out with ``git worktree add`` into a temporary directory, removed at the end, with main's
SERVE_FLAGS and ``--loop asyncio``: main's own dependencies have no uvloop). One solver worker each
(``VIBFREE_WORKERS=1``): the measured requests never use it.

Measured, p50 over interleaved repeats (old, new, old, new, ...: both see the same machine load):

- a 100k-sample ``/v1/simulate`` (``time_s`` and ``velocity`` sent, a 5 Hz mode): the JSON answer (target
  <= 50 ms), the same as npz (``Accept: application/x-npz``) and with a narrow ``fields=load.position,metrics``;
- a 1k-sample STAP closed form (``/v1/profiles/stap``, Cusimano Sec. 3, k_j = 1) over HTTP (target <= 3 ms),
  beside the same request in-process: ``app.services.profile.design`` (parsing the body into the model, the design,
  sampling, simulation, metrics: the service layer's time) and that plus writing the JSON answer;
- what the client itself costs: the same client (``http.client``, one persistent connection) fetching the
  same number of bytes from a raw-socket responder in this process that sends a prebuilt answer (no HTTP
  framework): the floor of client plus loopback transport;
- the in-process breakdown of the 100k simulate on this worktree (parse, validate, to numpy, simulate,
  metrics, render), to see where the HTTP time goes.

Run: python bench/http_io.py [repeats]   (default 15 for the 100k cases, 20x that for STAP)
"""

from __future__ import annotations

import asyncio
import http.client
import json
import logging
import os
import re
import shlex
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import orjson
import structlog

ROOT = Path(__file__).resolve().parent.parent
logging.disable(logging.INFO)  # the in-process runs' solve lines (stdlib)
structlog.configure(wrapper_class=structlog.make_filtering_bound_logger(logging.WARNING))  # (structlog)
sys.path.insert(0, str(ROOT))

OLD_COMMIT = "e89cdee"
ALL = ("main", "new", "httptools")
SAMPLES = 100_000
STAP_SAMPLES = 1_000
TARGET_SIMULATE_MS = 50.0
TARGET_STAP_MS = 3.0
STAP_HORIZON_S = 0.175 + 5 / 40.0  # t_a = 0.175 s (eq. 61) and 5 periods of the 40 Hz mode
STAP_REQUEST = {
    "plant": {"kind": "mode", "natural_frequency_hz": 40.0, "damping_ratio": 0.0},
    "target_velocity": 150.0,
    "limits": {"max_acceleration": 1000.0},
    "jerk_periods": 1,
    "sample_period_s": STAP_HORIZON_S / (STAP_SAMPLES - 1),
}


def simulate_request(samples: int) -> dict[str, Any]:
    """A smooth velocity command over 1 s (a raised cosine), sampled at ``samples`` instants, on a 5 Hz mode."""
    t = np.linspace(0.0, 1.0, samples)
    v = 0.5 * (1.0 - np.cos(2.0 * np.pi * t))
    return {
        "plant": {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": 0.02},
        "profile": {"time_s": t, "velocity": v},
    }


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def serve_flags(checkout: Path) -> list[str]:
    """The Makefile's SERVE_FLAGS (continuation lines joined), without any process-count flag."""
    text = (checkout / "Makefile").read_text()
    match = re.search(r"^SERVE_FLAGS \?=((?:.*\\\n)*.*)$", text, re.MULTILINE)
    assert match, "no SERVE_FLAGS in the Makefile"
    flags = shlex.split(match.group(1).replace("\\\n", " "))
    out: list[str] = []
    skip = False
    for flag in flags:
        if skip:
            skip = False
        elif flag == "--workers":
            skip = True
        elif not flag.startswith("--workers="):
            out.append(flag)
    return out


def with_http(flags: list[str], http: str | None) -> list[str]:
    """``flags`` with another ``--http`` implementation (and without h11's own option), or as they are."""
    if http is None:
        return flags
    out: list[str] = []
    skip = False
    for flag in flags:
        if skip:
            skip = False
        elif flag in ("--http", "--h11-max-incomplete-event-size"):
            skip = True
        else:
            out.append(flag)
    return [*out, "--http", http]


class Server:
    """uvicorn serving one checkout's app on a free port, until ``stop``."""

    def __init__(self, name: str, checkout: Path, extra: list[str], http: str | None = None) -> None:
        self.name = name
        self.port = free_port()
        self.flags = with_http(serve_flags(checkout), http) + extra
        env = {**os.environ, "PYTHONPATH": str(checkout), "VIBFREE_WORKERS": "1"}
        command = [sys.executable, "-m", "uvicorn", "app.main:app", "--host", "127.0.0.1", "--port", str(self.port)]
        self.process = subprocess.Popen(
            [*command, *self.flags], cwd=checkout, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )

    def wait_ready(self, timeout_s: float = 300.0) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            assert self.process.poll() is None, f"the {self.name} server exited"
            try:
                connection = http.client.HTTPConnection("127.0.0.1", self.port, timeout=5)
                connection.request("GET", "/readyz")
                if connection.getresponse().status == 200:
                    connection.close()
                    return
                connection.close()
            except OSError:
                pass
            time.sleep(0.25)
        raise AssertionError(f"the {self.name} server did not become ready")

    def stop(self) -> None:
        self.process.terminate()
        try:
            self.process.wait(30)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(10)


class Client:
    """One persistent ``http.client`` connection; ``post`` returns (seconds, status, headers, body bytes)."""

    def __init__(self, port: int) -> None:
        self.connection = http.client.HTTPConnection("127.0.0.1", port, timeout=120)

    def post(
        self, path: str, body: bytes, accept: str = "application/json"
    ) -> tuple[float, int, dict[str, str], bytes]:
        headers = {"content-type": "application/json", "accept": accept}
        for attempt in (1, 2):
            try:
                started = time.perf_counter()
                self.connection.request("POST", path, body=body, headers=headers)
                response = self.connection.getresponse()
                data = response.read()
                elapsed = time.perf_counter() - started
                break
            except (ConnectionError, http.client.RemoteDisconnected):  # closed after 5 s idle (keep-alive)
                self.connection.close()
                if attempt == 2:
                    raise
        return elapsed, response.status, dict(response.getheaders()), data

    def close(self) -> None:
        self.connection.close()


class RawResponder:
    """A raw-socket server that answers every request with one prebuilt HTTP response: what a client and the
    loopback transport cost for that many bytes, without any server framework."""

    def __init__(self, body: bytes) -> None:
        head = f"HTTP/1.1 200 OK\r\ncontent-type: application/json\r\ncontent-length: {len(body)}\r\n\r\n"
        self.response = head.encode() + body
        self.socket = socket.socket()
        self.socket.bind(("127.0.0.1", 0))
        self.socket.listen(1)
        self.port = int(self.socket.getsockname()[1])
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        try:
            connection, _ = self.socket.accept()
        except OSError:
            return
        with connection:
            buffer = b""
            while True:
                chunk = connection.recv(1 << 20)
                if not chunk:
                    return
                buffer += chunk
                while b"\r\n\r\n" in buffer:
                    head, _, rest = buffer.partition(b"\r\n\r\n")
                    length = int(re.search(rb"content-length: *(\d+)", head, re.IGNORECASE).group(1))  # type: ignore[union-attr]
                    while len(rest) < length:
                        rest += connection.recv(1 << 20)
                    buffer = rest[length:]
                    connection.sendall(self.response)

    def close(self) -> None:
        self.socket.close()


def p50_ms(samples: list[float]) -> float:
    return 1e3 * statistics.median(samples)


def in_process_stap(repeats: int) -> tuple[float, float]:
    """p50 of ``profiles.design`` for the STAP request, and of it plus the JSON answer, in this process (ms)."""
    from app.responses import Output, render
    from app.schemas.stap import FAMILY, StapIn
    from app.services import profile as profiles
    from app.settings import Settings

    settings = Settings(workers=1)
    output = Output(csv=False, columns=None, comments=False)

    async def design() -> None:
        body = StapIn.model_validate(STAP_REQUEST)
        await profiles.design(FAMILY, body, settings, None)  # type: ignore[arg-type]  # closed form: no pool

    async def answer() -> None:
        body = StapIn.model_validate(STAP_REQUEST)
        answer, _ = await profiles.design(FAMILY, body, settings, None)  # type: ignore[arg-type]
        render(output, answer).body  # noqa: B018

    async def timed(call: Callable[[], Any]) -> list[float]:
        times = []
        for _ in range(repeats):
            started = time.perf_counter()
            await call()
            times.append(time.perf_counter() - started)
        return times

    async def both() -> tuple[list[float], list[float]]:
        await design()
        return await timed(design), await timed(answer)

    designs, answers = asyncio.run(both())
    return p50_ms(designs), p50_ms(answers)


def in_process_simulate(body: bytes, repeats: int) -> dict[str, float]:
    """The 100k simulate in this process, step by step (p50, ms): what the HTTP path adds to the computation."""
    from app.json_bodies import parse_json
    from app.presenters import load_json, metrics_json
    from app.responses import Output, render
    from app.schemas.plants import to_plant
    from app.schemas.simulate import SimulateRequest, to_command
    from models.metrics import metrics
    from models.simulation import simulate
    from optim.problem import VIBRATION_FRACTION_OF_MOVE
    from optim.results import MetricsReport
    from optim.synthesis import profile_arrays

    steps: dict[str, list[float]] = {
        k: [] for k in ("json.loads", "orjson parse", "validate", "to numpy", "simulate", "metrics", "render JSON")
    }
    output = Output(csv=False, columns=None, comments=False)
    for _ in range(repeats):
        marks = [time.perf_counter()]
        json.loads(body)
        marks.append(time.perf_counter())
        parsed = parse_json(body)
        marks.append(time.perf_counter())
        request = SimulateRequest.model_validate(parsed)
        marks.append(time.perf_counter())
        command, _ = to_command(request.profile, request, SAMPLES)
        marks.append(time.perf_counter())
        response = simulate(to_plant(request.plant), command)
        marks.append(time.perf_counter())
        tolerance, window = request.settling_criteria()
        result = metrics(response, tolerance, None, window, vibration_fraction=VIBRATION_FRACTION_OF_MOVE)
        marks.append(time.perf_counter())
        answer = {
            "profile": profile_arrays(command),
            "load": load_json(response),
            "metrics": metrics_json(MetricsReport(result)),
        }
        render(output, {**answer, "warnings": []}).body  # noqa: B018
        marks.append(time.perf_counter())
        for name, start, end in zip(steps, marks, marks[1:], strict=False):
            steps[name].append(end - start)
    return {name: p50_ms(times) for name, times in steps.items()}


def add_old_worktree() -> Path:
    path = Path(tempfile.gettempdir()) / "wt-io-old"
    if path.exists():
        subprocess.run(["git", "worktree", "remove", "--force", str(path)], cwd=ROOT, check=False)
    subprocess.run(
        ["git", "worktree", "add", "--detach", str(path), OLD_COMMIT],
        cwd=ROOT,
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    return path


def main(repeats: int = 15) -> int:
    old_checkout = add_old_worktree()
    servers: list[Server] = []
    try:
        servers = [
            Server("main", old_checkout, ["--loop", "asyncio"]),
            Server("new", ROOT, []),
            Server("httptools", ROOT, [], http="httptools"),  # what the h11 pin costs (docs/deployment.md)
        ]
        for server in servers:
            server.wait_ready()
        print(f"main ({OLD_COMMIT}) flags: {' '.join(servers[0].flags)}")
        print(f"new flags: {' '.join(servers[1].flags)}")
        print(f"httptools (this worktree, not served: no header cap) flags: {' '.join(servers[2].flags)}")
        return run(servers, repeats)
    finally:
        for server in servers:
            server.stop()
        subprocess.run(["git", "worktree", "remove", "--force", str(old_checkout)], cwd=ROOT, check=False)


def run(servers: list[Server], repeats: int) -> int:
    simulate_body = orjson.dumps(simulate_request(SAMPLES), option=orjson.OPT_SERIALIZE_NUMPY)
    stap_body = orjson.dumps(STAP_REQUEST)
    clients = {s.name: Client(s.port) for s in servers}
    cases: list[tuple[str, str, bytes, str, tuple[str, ...], int]] = [
        ("simulate 100k JSON", "/v1/simulate", simulate_body, "application/json", ALL, repeats),
        ("simulate 100k npz", "/v1/simulate", simulate_body, "application/x-npz", ("new",), repeats),
        (
            "simulate 100k fields=load.position,metrics",
            "/v1/simulate?fields=load.position,metrics",
            simulate_body,
            "application/json",
            ("new",),
            repeats,
        ),
        ("STAP 1k closed form JSON", "/v1/profiles/stap", stap_body, "application/json", ALL, 20 * repeats),
    ]
    results: dict[tuple[str, str], list[float]] = {}
    sizes: dict[tuple[str, str], int] = {}
    answers: dict[tuple[str, str], bytes] = {}
    failures: list[str] = []
    for label, path, body, accept, names, count in cases:
        for name in names:  # one warm call each
            _, status, _, data = clients[name].post(path, body, accept)
            if status != 200:
                failures.append(f"{label} on {name}: {status} {data[:300]!r}")
        for _ in range(count):
            for name in names:
                elapsed, status, _, data = clients[name].post(path, body, accept)
                results.setdefault((label, name), []).append(elapsed)
                sizes[(label, name)] = len(data)
                answers[(label, name)] = data
    for client in clients.values():
        client.close()

    stap_design_ms, stap_answer_ms = in_process_stap(20 * repeats)
    floors = {}
    for label in ("simulate 100k JSON", "STAP 1k closed form JSON"):
        responder = RawResponder(answers[(label, "new")])
        client = Client(responder.port)
        body = simulate_body if label.startswith("simulate") else stap_body
        times = [client.post("/", body)[0] for _ in range(repeats if label.startswith("simulate") else 20 * repeats)]
        client.close()
        responder.close()
        floors[label] = p50_ms(times)
    steps = in_process_simulate(simulate_body, max(5, repeats // 3))

    print(
        f"\nrequest bodies: simulate {len(simulate_body) / 1e6:.2f} MB, STAP {len(stap_body)} B; "
        "p50 over interleaved runs"
    )
    print(
        f"{'case':44s} {'main ms':>8s} {'new ms':>8s} {'main/new':>8s} {'httptools ms':>12s} "
        f"{'answer MB main -> new':>22s}"
    )
    main_json = p50_ms(results[("simulate 100k JSON", "main")])
    for label, _, _, _, names, _ in cases:
        new = p50_ms(results[(label, "new")])
        old = p50_ms(results[(label, "main")]) if "main" in names else main_json  # npz, fields: against main's JSON
        old_text = f"{old:8.2f}" if "main" in names else f"{'(JSON)':>8s}"
        fast = f"{p50_ms(results[(label, 'httptools')]):12.2f}" if "httptools" in names else f"{'':12s}"
        old_size = sizes.get((label, "main"), sizes[("simulate 100k JSON", "main")])
        size = f"{old_size / 1e6:8.3f} -> {sizes[(label, 'new')] / 1e6:.3f}"
        print(f"{label:44s} {old_text} {new:8.2f} {old / new:8.2f} {fast} {size:>22s}")
    stap_new = p50_ms(results[("STAP 1k closed form JSON", "new")])
    stap_old = p50_ms(results[("STAP 1k closed form JSON", "main")])
    print(
        f"\nSTAP 1k in-process (this worktree): profiles.design {stap_design_ms:.2f} ms, with the JSON answer "
        f"{stap_answer_ms:.2f} ms"
    )
    print(
        f"  HTTP / in-process answer: main {stap_old / stap_answer_ms:.2f}, new {stap_new / stap_answer_ms:.2f}; "
        f"HTTP overhead main {stap_old - stap_answer_ms:.2f} ms, new {stap_new - stap_answer_ms:.2f} ms"
    )
    print(
        "client + loopback floor (same client, a raw socket answering the same bytes): "
        + ", ".join(f"{k} {v:.2f} ms" for k, v in floors.items())
    )
    print(
        "in-process 100k simulate steps (this worktree, p50 ms): " + ", ".join(f"{k} {v:.2f}" for k, v in steps.items())
    )

    if p50_ms(results[("simulate 100k JSON", "new")]) > TARGET_SIMULATE_MS:
        failures.append(f"simulate 100k JSON p50 above {TARGET_SIMULATE_MS:g} ms")
    if stap_new > TARGET_STAP_MS:
        failures.append(f"STAP 1k p50 above {TARGET_STAP_MS:g} ms")
    for failure in failures:
        print("MISS", failure)
    return 0  # a missed target is printed, like the other benchmarks: make bench runs them all


if __name__ == "__main__":
    sys.exit(main(*(int(a) for a in sys.argv[1:2])))
