"""A real server in a subprocess (``vibfree serve``: uvicorn's supervisor and its HTTP processes), for the tests
and benches that need several processes; always stopped, its whole process group, when the block ends."""

from __future__ import annotations

import contextlib
import http.client
import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def get(port: int, path: str, timeout_s: float = 10.0) -> tuple[int, bytes]:
    """One GET on a fresh connection (so that any HTTP process may take it)."""
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout_s)
    try:
        connection.request("GET", path)
        response = connection.getresponse()
        return response.status, response.read()
    finally:
        connection.close()


def readyz(port: int) -> tuple[int, dict]:
    status, body = get(port, "/readyz")
    return status, json.loads(body)


def wait_ready(port: int, timeout_s: float = 180.0, process: subprocess.Popen | None = None) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if process is not None and process.poll() is not None:
            raise AssertionError(f"the server exited with {process.returncode}")
        with contextlib.suppress(OSError):
            status, body = readyz(port)
            if status == 200:
                return body
        time.sleep(0.25)
    raise AssertionError("the server did not become ready")


@contextlib.contextmanager
def serving(
    processes: int | None, root: Path = ROOT, env: dict[str, str] | None = None, extra: tuple[str, ...] = ()
) -> Iterator[int]:
    """``vibfree serve`` from ``root`` on a free port until the block ends; yields the port.

    ``processes`` None: the default of the settings (one per core); ``processes`` 0: plain uvicorn (one process,
    no ``vibfree serve``: an older checkout) with ``extra`` flags. The server's own stderr goes to a file
    in the system's temporary directory (JSON lines), so a failing test can show it."""
    port = free_port()
    command = [sys.executable, "-m", "vibfree.cli", "serve", "--port", str(port)]
    if processes == 0:
        command = [sys.executable, "-m", "uvicorn", "app.main:app", "--port", str(port), "--no-access-log", *extra]
    elif processes is not None:
        command += ["--processes", str(processes)]
    environment = {**os.environ, "PYTHONPATH": str(root), **(env or {})}
    environment.pop("PROMETHEUS_MULTIPROC_DIR", None)  # the command makes a fresh one
    log = open(os.path.join(os.environ.get("TMPDIR", "/tmp"), f"vibfree-serve-{port}.log"), "wb")  # noqa: SIM115
    process = subprocess.Popen(command, cwd=root, env=environment, stdout=log, stderr=log, start_new_session=True)
    try:
        wait_ready(port, process=process)
        yield port
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(40)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGKILL)
            process.wait(10)
        log.close()


def scrape(port: int) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    """The /metrics samples: (name, sorted labels) -> value."""
    from prometheus_client.parser import text_string_to_metric_families

    status, body = get(port, "/metrics")
    assert status == 200
    return {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in text_string_to_metric_families(body.decode())
        for s in family.samples
    }
