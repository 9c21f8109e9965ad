"""Where the commands run: what they may import, the files they find, the server they talk to, and the runner."""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import tomllib
import urllib.request
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from functools import cache
from importlib import metadata
from pathlib import Path
from typing import Any

from tests.app.server import free_port, serving
from tests.docs_commands.documented import (
    SWEEP_POINTS,
    SWEEP_REFINED,
    documented_program,
    documented_request,
    documented_sweep,
    identification_record_script,
)
from tests.docs_commands.extract import ROOT, commands, key, language, uncommented

VENV_BIN = Path(sys.executable).parent
SERVICE = re.compile(r"\b(?:localhost|127\.0\.0\.1):8000\b")
SERVER_ENV = {"VIBFREE_WORKERS": "1"}


# --- what runs a command may import: what pip install . installs, and the extras it names -------------------------

SITECUSTOMIZE = '''\
"""Written by tests/docs_commands/sandbox.py: the installed packages pip install . would not install are hidden."""

import importlib.machinery
import os
import sys

_HIDDEN = frozenset(os.environ.get("VIBFREE_DOCS_HIDDEN", "").split(","))


class _InstalledByPipInstall(importlib.machinery.PathFinder):
    @classmethod
    def find_spec(cls, fullname, path=None, target=None):
        if fullname.partition(".")[0] in _HIDDEN:
            return None
        return super().find_spec(fullname, path, target)


sys.meta_path[:] = [
    _InstalledByPipInstall if finder is importlib.machinery.PathFinder else finder for finder in sys.meta_path
]
'''
BOOTSTRAP = {"pip", "setuptools"}  # in every venv, the one make serve creates too


@cache
def hidden_modules(extras: tuple[str, ...] = ()) -> str:
    """The installed top-level modules no distribution of ``pip install '.[extras]'`` provides, comma-separated."""
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    wanted = [*project["dependencies"], *(dep for extra in extras for dep in project["optional-dependencies"][extra])]
    todo = [Requirement(dep) for dep in wanted]
    seen: set[tuple[str, str]] = set()
    while todo:
        requirement = todo.pop()
        name = canonicalize_name(requirement.name)
        for extra in ("", *sorted(requirement.extras)):
            if (name, extra) in seen:
                continue
            seen.add((name, extra))
            with contextlib.suppress(metadata.PackageNotFoundError):
                for text in metadata.distribution(name).requires or []:
                    dependency = Requirement(text)
                    marker = dependency.marker
                    if (marker is None and not extra) or (marker is not None and marker.evaluate({"extra": extra})):
                        todo.append(dependency)
    allowed = {name for name, _ in seen} | BOOTSTRAP | {"vibfree"}
    hidden = {
        module
        for module, distributions in metadata.packages_distributions().items()
        if not {canonicalize_name(d) for d in distributions} & allowed
    }
    return ",".join(sorted(hidden))


# --- running ---------------------------------------------------------------------------------------------------


@dataclass(repr=False)
class Ran:
    command: str  # as run
    cwd: Path
    returncode: int
    stdout: str
    stderr: str
    written: frozenset[str] = frozenset()
    port: int | None = None
    seconds: float = 0.0

    def __repr__(self) -> str:  # what a failing check shows
        tail = f"--- stdout\n{self.stdout[-3000:]}\n--- stderr\n{self.stderr[-3000:]}"
        return f"$ {self.command}\nexit {self.returncode} after {self.seconds:.1f} s\n{tail}"

    @property
    def http(self) -> list[tuple[int, str]]:
        """(status, media type) of each answer curl received, in order."""
        return [(int(code), kind) for code, kind in re.findall(r"^curl-answer: (\d+) ?(.*)$", self.stderr, re.M)]

    def json(self) -> Any:
        return json.loads(self.stdout)


@dataclass(frozen=True)
class Run:
    """Run the command and check it: ``check(ran)``; python blocks run ``python_check`` after the snippet, in its
    process."""

    check: Callable[[Ran], None]
    server: bool = False  # talks to the service: waits for it, localhost:8000 is its address
    extras: tuple[str, ...] = ()  # the optional extras the command's text says it needs
    python_check: str = ""
    background: str | None = None  # a command that serves until stopped: this path of it must answer 200
    needs: tuple[str, ...] = ()  # earlier commands of its block whose files it reads
    timeout_s: float = 120.0
    # fills the server's bounded queues (an identification's recommendation asks for 13 designs at once, two would
    # get a 503 busy): runs while no other exclusive command does, as a reader runs them, one after the other
    exclusive: bool = False


@dataclass(frozen=True)
class Exempt:
    """Not run, for ``reason``; ``dry_run`` (run from the checkout) shows what can be shown, and its output must
    hold ``dry_run_says``."""

    reason: str
    dry_run: str | None = None
    dry_run_says: str = ""


@dataclass(frozen=True)
class IsTheServer:
    """The command is the one the tests' server runs (tests/app/server.py), with another port and process count."""

    check: Callable[[Ran], None]
    reason: str


Spec = Run | Exempt | IsTheServer


class Server:
    """``serving()`` in a thread, so that it warms up while the blocks that need no server run."""

    def __init__(self, environment: dict[str, str]) -> None:
        self.ready = threading.Event()
        self.stop = threading.Event()
        self.port: int | None = None
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._serve, args=(environment,), daemon=True)
        self.thread.start()

    def _serve(self, environment: dict[str, str]) -> None:
        try:
            with serving(1, env=environment) as port:
                self.port = port
                self.ready.set()
                self.stop.wait()
        except BaseException as exc:
            self.error = exc
            self.ready.set()

    def wait(self) -> int:
        assert self.ready.wait(240), "the server did not start"
        if self.error is not None or self.port is None:
            raise AssertionError(f"the server did not start: {self.error!r}")
        return self.port

    def close(self) -> None:
        self.stop.set()
        self.thread.join(60)


def _snapshot(directory: Path) -> dict[str, tuple[int, int]]:
    return {
        str(p.relative_to(directory)): (p.stat().st_mtime_ns, p.stat().st_size)
        for p in directory.rglob("*")
        if p.is_file() and ".venv" not in p.parts
    }


class Runs:
    """The commands of the selected blocks, run in the background (three at a time, while the server warms up),
    each in a fresh directory with the files written by the commands it ``needs``; identical commands (comments
    aside) run once. ``result(body)`` waits for one block's."""

    def __init__(self, tmp: Path, bodies: list[str], specs: Mapping[str, Spec]) -> None:
        self.tmp = tmp
        self.specs = specs
        self.inputs = tmp / "inputs"
        self.environment = self._environment()
        self._prepare_inputs()
        planned = [(body, c, specs.get(key(c))) for body in bodies for c in commands(body, language(body))]
        needs_server = any(isinstance(s, IsTheServer) or (isinstance(s, Run) and s.server) for _, _, s in planned)
        self.server = Server({**self.environment, **SERVER_ENV}) if needs_server else None
        self.pool = ThreadPoolExecutor(3, thread_name_prefix="docs-command")
        self._tasks: dict[str, Future[Ran | None]] = {}
        self._exclusive = threading.Lock()
        try:
            for body, command, spec in sorted(planned, key=lambda planned: _order(planned[2])):
                self._submit(body, command, spec)
        except BaseException:
            self.close()
            raise

    def result(self, body: str) -> list[tuple[str, Spec | None, Ran | None]]:
        return [
            (command, self.specs.get(key(command)), self._tasks[uncommented(command)].result(timeout=600))
            for command in commands(body, language(body))
        ]

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)
        if self.server is not None:
            self.server.close()

    def _submit(self, body: str, command: str, spec: Spec | None) -> Future[Ran | None]:
        text = uncommented(command)
        if text not in self._tasks:
            needed = []
            for name in spec.needs if isinstance(spec, Run) else ():
                (earlier,) = [c for c in commands(body, language(body)) if key(c) == name]
                needed.append(self._submit(body, earlier, self.specs.get(name)))  # first: the pool takes tasks in order
            self._tasks[text] = self.pool.submit(self._run, command, spec, needed, len(self._tasks))
        return self._tasks[text]

    def _run(self, command: str, spec: Spec | None, needed: list[Future[Ran | None]], number: int) -> Ran | None:
        if isinstance(spec, Exempt):
            return _run(spec.dry_run, ROOT, self.environment, 60) if spec.dry_run else None
        if isinstance(spec, IsTheServer):
            assert self.server is not None
            return Ran(command, ROOT, 0, "", "", port=self.server.wait())
        if spec is None:
            return None
        directory = self.tmp / f"command-{number}"
        shutil.copytree(self.inputs, directory)
        (directory / ".venv").symlink_to(Path(sys.prefix))  # .venv/bin/... in the docs: the venv make test makes
        for future in needed:
            earlier = future.result(timeout=600)
            assert earlier is not None
            for name in earlier.written:
                shutil.copy(earlier.cwd / name, directory / name)
        return self._run_command(command, spec, directory)

    def _environment(self) -> dict[str, str]:
        site = self.tmp / "site"
        site.mkdir()
        (site / "sitecustomize.py").write_text(SITECUSTOMIZE)
        curl_home = self.tmp / "curl"
        curl_home.mkdir()
        (curl_home / ".curlrc").write_text('write-out = "%{stderr}curl-answer: %{http_code} %{content_type}\\n"\n')
        environment = {
            **os.environ,
            "PATH": f"{VENV_BIN}{os.pathsep}{os.environ.get('PATH', '')}",
            "PYTHONPATH": f"{site}{os.pathsep}{ROOT}",
            "VIBFREE_DOCS_HIDDEN": hidden_modules(),
            "CURL_HOME": str(curl_home),
            "OMP_NUM_THREADS": "1",
        }
        for name in ("PROMETHEUS_MULTIPROC_DIR", "VIRTUAL_ENV", "PYTHONHOME"):
            environment.pop(name, None)
        return environment

    def _prepare_inputs(self) -> None:
        self.inputs.mkdir()
        (self.inputs / "request.json").write_text(documented_request())
        (self.inputs / "sweep.json").write_text(json.dumps(documented_sweep(SWEEP_POINTS, SWEEP_REFINED), indent=2))
        (self.inputs / "program.json").write_text(documented_program())
        record = subprocess.run(
            [sys.executable, "-"], input=identification_record_script(), cwd=self.inputs, text=True, timeout=60
        )
        assert record.returncode == 0 and (self.inputs / "record.csv").is_file()
        shutil.copy(ROOT / "mkdocs.yml", self.inputs / "mkdocs.yml")
        shutil.copytree(ROOT / "docs", self.inputs / "docs")

    def _run_command(self, command: str, spec: Run, directory: Path) -> Ran:
        port = None
        if spec.server:
            assert self.server is not None
            port = self.server.wait()
            command = SERVICE.sub(f"127.0.0.1:{port}", command)
        environment = dict(self.environment)
        if spec.extras:
            environment["VIBFREE_DOCS_HIDDEN"] = hidden_modules(spec.extras)
        with self._exclusive if spec.exclusive else contextlib.nullcontext():
            started = time.monotonic()
            if spec.python_check:
                ran = _run(
                    [sys.executable, "-c", command + "\n" + spec.python_check], directory, environment, spec.timeout_s
                )
                ran.command = command
            elif spec.background:
                ran = _run_in_background(command, spec.background, directory, environment, spec.timeout_s)
            else:
                before = _snapshot(directory)
                ran = _run(command, directory, environment, spec.timeout_s)
                after = _snapshot(directory)
                ran.written = frozenset(name for name, stamp in after.items() if before.get(name) != stamp)
            ran.port, ran.seconds = port, time.monotonic() - started
        return ran


def _order(spec: Spec | None) -> int:
    """Dry runs, then what runs in-process (each imports the service, ~4 s of CPU), then what needs the server."""
    if isinstance(spec, Run):
        return 3 if spec.server else 2 if spec.background else 1
    return 4 if isinstance(spec, IsTheServer) else 0


def _run(command: str | list[str], cwd: Path, environment: dict[str, str], timeout_s: float) -> Ran:
    shell = ["bash", "-e", "-o", "pipefail", "-c", command] if isinstance(command, str) else command
    result = subprocess.run(shell, cwd=cwd, env=environment, capture_output=True, text=True, timeout=timeout_s)
    return Ran(str(command), cwd, result.returncode, result.stdout, result.stderr)


def _run_in_background(command: str, path: str, cwd: Path, environment: dict[str, str], timeout_s: float) -> Ran:
    """A command that serves until stopped (its port rewritten to a free one): started, ``path`` fetched when it
    answers, stopped."""
    port = free_port()
    command = re.sub(r"127\.0\.0\.1:\d+", f"127.0.0.1:{port}", command)
    log = cwd / "background.log"
    with log.open("wb") as out:
        process = subprocess.Popen(
            ["bash", "-c", f"exec {command}"], cwd=cwd, env=environment, stdout=out, stderr=out, start_new_session=True
        )
    page, deadline = "", time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline and process.poll() is None and not page:
            with (
                contextlib.suppress(OSError),
                urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=5) as answer,
            ):
                page = answer.read().decode()
            time.sleep(0.2)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(20)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(10)
    return Ran(command, cwd, 0 if page else 1, page, log.read_text(errors="replace"), port=port)
