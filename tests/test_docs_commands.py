"""Every command in README.md and docs/*.md is run (issue 24).

Every fenced block of the README and of docs/*.md is either commands (``sh``, ``python``) or not (``text``,
``json``, ``ini``: a tree, an output listing, a body). Every command of a command block is in ``COMMANDS``: run,
with a check of what it answers, or exempt with the reason it cannot run in a test. A command in neither, or an
entry whose command is gone, fails ``test_every_command_is_run_or_exempt``.

The commands run as written, each in a fresh directory (holding what the earlier commands of its block that it
``needs`` wrote), with these changes only:

- ``localhost:8000`` (or ``127.0.0.1:8000``) is one ``vibfree serve`` (tests/app/server.py) on a free port, with
  one HTTP process and one solver worker (warm in ~13 s; the documented two processes take ~35 s here);
- ``vibfree``, ``python``, ``python3`` and ``.venv/bin/`` are this environment's, importing this checkout;
- only what ``make serve`` (``pip install .``) installs can be imported, plus the extras the command's own text
  names (a ``sitecustomize`` hides the other installed packages): a snippet that imports pandas fails;
- curl writes each answer's status and media type on stderr (a ``.curlrc`` in ``CURL_HOME``);
- the files the docs describe in prose are there: ``request.json`` (the example below the command-line block),
  ``sweep.json`` (docs/sweeps.md's body, with 3 points and 1 refined: its 82 time-optimal designs take 48 s),
  ``record.csv`` (docs/identification.md's record), and ``mkdocs.yml`` with ``docs/`` for the site's commands.

The commands run three at a time while the server warms up; identical blocks (the README repeats some of
docs/) and identical commands run once. Most of their time is the service's import, ~4 s of CPU per command that
designs in-process.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
import tomllib
import urllib.request
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from decimal import Decimal
from functools import cache
from importlib import metadata
from pathlib import Path
from typing import Any

import pytest

from tests.app.server import free_port, serving

ROOT = Path(__file__).resolve().parent.parent
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
COMMAND_LANGUAGES = {"sh", "python"}
DATA_LANGUAGES = {"text", "json", "ini"}
VENV_BIN = Path(sys.executable).parent
SERVICE = re.compile(r"\b(?:localhost|127\.0\.0\.1):8000\b")
SERVER_ENV = {"VIBFREE_WORKERS": "1"}
SWEEP_POINTS, SWEEP_REFINED = 3, 1  # sweep.json: docs/sweeps.md's body with fewer points (82 designs take 48 s)


# --- the blocks and their commands -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Block:
    document: str
    line: int
    language: str
    body: str

    def __str__(self) -> str:
        return f"{self.document}:{self.line} ({self.language or 'no language'})"


FENCE = re.compile(
    r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})(?P<info>[^\n`]*)\n(?P<body>.*?)^(?P=indent)(?P=fence)[ \t]*$",
    re.M | re.S,
)


@cache
def blocks() -> tuple[Block, ...]:
    found = []
    for path in DOCUMENTS:
        text = path.read_text()
        for match in FENCE.finditer(text):
            indent = match["indent"]
            body = "".join(line.removeprefix(indent) for line in match["body"].splitlines(keepends=True))
            language = match["info"].strip().split(" ")[0]
            line = text.count("\n", 0, match.start()) + 1
            found.append(Block(str(path.relative_to(ROOT)), line, language, body))
    return tuple(found)


def command_blocks() -> dict[str, list[Block]]:
    """The distinct bodies of the command blocks, each with the places it is written."""
    bodies: dict[str, list[Block]] = {}
    for block in blocks():
        if block.language in COMMAND_LANGUAGES:
            bodies.setdefault(block.body, []).append(block)
    return bodies


def commands(body: str, language: str) -> list[str]:
    """A python block is one command; a shell block's are its top-level commands (continued lines, quotes spanning
    lines and here-documents joined; comment lines between them dropped)."""
    if language == "python":
        return [body]
    found: list[str] = []
    current: list[str] = []
    heredoc: str | None = None
    for line in body.splitlines():
        if heredoc is not None:
            current.append(line)
            if line.strip() == heredoc:
                found.append("\n".join(current))
                current, heredoc = [], None
            continue
        if not current and (not line.strip() or line.lstrip().startswith("#")):
            continue
        current.append(line)
        if marker := re.search(r"<<-?\s*(['\"]?)(\w+)\1", line):
            heredoc = marker[2]
        elif not line.endswith("\\") and _quotes_closed("\n".join(current)):
            found.append("\n".join(current))
            current = []
    assert not current, f"an unfinished command: {current}"
    return found


def _quotes_closed(text: str) -> bool:
    try:
        shlex.split(text, comments=True)
    except ValueError:
        return False
    return True


def uncommented(command: str) -> str:
    """The command without its comments (a ``#`` that starts a word outside quotes, to the end of its line)."""
    kept, quote, comment, previous = [], "", False, "\n"
    for char in command:
        if comment and char == "\n":
            comment = False
        elif not comment and quote and char == quote:
            quote = ""
        elif not comment and not quote and char in "'\"":
            quote = char
        elif not comment and not quote and char == "#" and previous.isspace():
            comment = True
        if not comment:
            kept.append(char)
        previous = char
    return "\n".join(line.rstrip() for line in "".join(kept).splitlines())


def key(command: str) -> str:
    """What names a command in COMMANDS: its first line without its comment."""
    return uncommented(command).splitlines()[0].removesuffix("\\").strip()


# --- what runs a command may import: what pip install . installs, and the extras it names -------------------------

SITECUSTOMIZE = '''\
"""Written by tests/test_docs_commands.py: the installed packages pip install . would not install are hidden."""

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

    def __init__(self, tmp: Path, bodies: list[str]) -> None:
        self.tmp = tmp
        self.inputs = tmp / "inputs"
        self.environment = self._environment()
        self._prepare_inputs()
        planned = [(body, c, COMMANDS.get(key(c))) for body in bodies for c in commands(body, _language(body))]
        needs_server = any(isinstance(s, IsTheServer) or (isinstance(s, Run) and s.server) for _, _, s in planned)
        self.server = Server({**self.environment, **SERVER_ENV}) if needs_server else None
        self.pool = ThreadPoolExecutor(3, thread_name_prefix="docs-command")
        self._tasks: dict[str, Future[Ran | None]] = {}
        try:
            for body, command, spec in sorted(planned, key=lambda planned: _order(planned[2])):
                self._submit(body, command, spec)
        except BaseException:
            self.close()
            raise

    def result(self, body: str) -> list[tuple[str, Spec | None, Ran | None]]:
        return [
            (command, COMMANDS.get(key(command)), self._tasks[uncommented(command)].result(timeout=600))
            for command in commands(body, _language(body))
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
                (earlier,) = [c for c in commands(body, _language(body)) if key(c) == name]
                needed.append(self._submit(body, earlier, COMMANDS.get(name)))  # first: the pool takes tasks in order
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


def _language(body: str) -> str:
    return command_blocks()[body][0].language


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


# --- inputs the docs describe in prose ---------------------------------------------------------------------------


def documented_request() -> str:
    """The example below the command-line block: ``request.json`` is the endpoint's request body, e.g. ..."""
    text = (ROOT / "docs" / "cli-and-python.md").read_text()
    (body,) = re.findall(r"`request\.json` is the endpoint's request body.*?e\.g\.\s*`(\{.*?\})`", text, re.S)
    assert body in (ROOT / "README.md").read_text()
    return body


def documented_sweep(points: int, refined: int) -> dict:
    """docs/sweeps.md's body (``sweep.json`` is the body above), with ``points`` points and ``refined`` added."""
    (body,) = [b.body for b in blocks() if b.document == "docs/sweeps.md" and b.language == "json"]
    sweep = json.loads(body)
    (axis,) = sweep["axes"]
    assert axis["num"] >= points and sweep["max_refined_points"] >= refined
    axis["num"], sweep["max_refined_points"] = points, refined
    return sweep


def documented_table_columns() -> list[str]:
    """docs/sweeps.md: the table's columns after the axes' values."""
    text = (ROOT / "docs" / "sweeps.md").read_text()
    (columns,) = re.findall(r"the axes' values, then (.*?)\. The check", text, re.S)
    return re.findall(r"`(\w+)`", columns)


def identification_record_script() -> str:
    (command,) = [
        c
        for b in blocks()
        if b.document == "docs/identification.md" and b.language == "sh"
        for c in commands(b.body, "sh")
        if c.startswith("python3 - <<")
    ]
    return command.split("\n", 1)[1].rsplit("\n", 1)[0]


def documented_identification_answer() -> dict:
    (body,) = [b.body for b in blocks() if b.document == "docs/identification.md" and b.language == "json"]
    return json.loads(body, parse_float=Decimal)


def matches_listing(listing: Any, answer: Any, where: str = "answer") -> None:
    """A shortened listing (``"...": "..."`` keys, ``["..."]`` lists) agrees with the answer: its keys are there,
    its strings equal, its numbers equal to the digits printed."""
    if isinstance(listing, dict):
        assert isinstance(answer, dict), where
        for name, value in listing.items():
            if name != "...":
                assert name in answer, f"{where}.{name} is not in the answer"
                matches_listing(value, answer[name], f"{where}.{name}")
    elif isinstance(listing, list):
        assert isinstance(answer, list), where
        if not (len(listing) == 1 and isinstance(listing[0], str) and listing[0].startswith("...")):
            assert len(listing) == len(answer), where
            for n, (value, actual) in enumerate(zip(listing, answer, strict=True)):
                matches_listing(value, actual, f"{where}[{n}]")
    elif isinstance(listing, Decimal):
        exponent = listing.as_tuple().exponent
        assert isinstance(exponent, int)
        assert abs(Decimal(repr(answer)) - listing) <= Decimal(5).scaleb(exponent - 1), (where, answer, listing)
    else:
        assert answer == listing, (where, answer, listing)


# --- the checks --------------------------------------------------------------------------------------------------


def ok(ran: Ran) -> None:
    assert ran.returncode == 0, ran


def answered(ran: Ran, *kinds: str) -> None:
    ok(ran)
    assert ran.http and all(status == 200 for status, _ in ran.http), ran
    assert all(any(kind.startswith(k) for k in kinds) for _, kind in ran.http), ran


def csv_rows(text: str) -> list[list[str]]:
    return list(csv.reader(line for line in io.StringIO(text) if not line.startswith("#")))


def check_readyz_loop(ran: Ran) -> None:
    answered(ran, "application/json")


def check_table_iii(ran: Ran) -> None:
    answered(ran, "application/json")
    answer = ran.json()
    assert answer["metrics"]["motion_time_s"] == 1.0 and answer["limits_met"]
    assert answer["profile"]["position"][-1] == pytest.approx(15 * 2 * 3.141592653589793)  # 15 revolutions
    assert answer["metrics"]["percentage_vibration"] < 1e-6  # no residual vibration


def check_time_optimal_band(ran: Ran) -> None:
    answered(ran, "application/json")
    answer = ran.json()
    nominal, five, ten = answer["tradeoff"]
    assert round(nominal["duration_s"] * 1e3, 2) == 219.71 and nominal["frequency_ratio_range"] == [1.0, 1.0]
    assert round(answer["design"]["rigid_duration_s"] * 1e3, 2) == 219.09
    robustness = answer["design"]["robustness"]
    assert robustness["covers_request"] and robustness["worst_percentage_vibration"] <= 5.0
    assert robustness["requested"]["frequency_ratio_range"] == [0.9, 1.1]
    assert [row["half_width"] for row in (nominal, five, ten)] == [0, 0.05, 0.1]
    assert all(row["status"] == "ok" for row in (nominal, five, ten))


def check_table_iii_csv(ran: Ran) -> None:
    answered(ran, "text/csv")
    assert ran.written == {"table-iii.csv"}, ran.written
    header, *rows = csv_rows((ran.cwd / "table-iii.csv").read_text())
    assert header == ["time_s", "position", "velocity", "load_position"]
    assert float(rows[1][0]) == 0.002  # one row per 2 ms
    assert float(rows[-1][1]) == pytest.approx(15 * 2 * 3.141592653589793)
    assert float(rows[-1][3]) == pytest.approx(3.141592653589793, rel=1e-6)  # the platform: half a turn


def check_help(ran: Ran) -> None:
    ok(ran)
    for command in ("design", "compare", "identify", "sweep", "serve"):
        assert re.search(rf"^\s+{command}\s", ran.stdout, re.M), ran


def check_design_stap_csv(ran: Ran) -> None:
    ok(ran)
    for line in ("duration  0.175 s", "settling  0.175 s", "residual ", "band 5 %"):
        assert line in ran.stdout, ran
    assert ran.written == {"out.csv"}, ran.written
    header, *rows = csv_rows((ran.cwd / "out.csv").read_text())
    assert header == ["time_s", "position", "velocity", "acceleration", "jerk"] and len(rows) > 100


def check_design_json(ran: Ran) -> None:
    ok(ran)
    answer = ran.json()
    assert {"profile", "metrics", "design"} <= set(answer) and answer["limits_met"]
    assert "duration " in ran.stderr and "settling " in ran.stderr, ran  # the summary


def check_design_by_url(ran: Ran) -> None:
    ok(ran)
    assert f"--url http://127.0.0.1:{ran.port}" in ran.command and "settling  0.175 s" in ran.stdout, ran
    text = (ran.cwd / "out.csv").read_text()
    assert text.startswith("# STAP profile") and "\n# units: " in text
    header, *_ = csv_rows(text)
    assert header[:2] == ["time_s", "position"] and {"load_position", "deflection"} <= set(header)


def check_compare(ran: Ran) -> None:
    ok(ran)
    header, *lines = ran.stdout.splitlines()
    assert header.split()[:3] == ["design", "settling", "duration"], ran
    designs = [line for line in lines if not line.startswith("unavailable")]
    assert {"time_optimal", "stap/closed_form", "input_shaped/zv"} <= {line.split()[0] for line in designs}, ran
    settling = [float(line.split()[1]) for line in designs]
    assert settling == sorted(settling), ran  # the ranking


def check_identify(ran: Ran) -> None:
    ok(ran)
    modes = [float(f) for f in re.findall(r"^mode (\S+) Hz \(95 %", ran.stdout, re.M)]
    assert [round(f) for f in modes] == [23, 61], ran
    assert "\nrecommended: " in ran.stdout and "POST /v1/profiles/" in ran.stdout, ran
    request = json.loads(ran.stdout.strip().splitlines()[-1])
    assert request["displacement"] == 0.12 and request["limits"] == {"max_velocity": 0.5, "max_acceleration": 10}


def check_sweep_table(ran: Ran) -> None:
    ok(ran)
    assert ran.written == {"table.csv"}, ran.written
    header, *rows = csv_rows((ran.cwd / "table.csv").read_text())
    assert header == ["plant.natural_frequency_hz", *documented_table_columns()]
    assert SWEEP_POINTS <= len(rows) <= SWEEP_POINTS + SWEEP_REFINED
    assert all(row[header.index("ok")] == "True" for row in rows)
    assert "table check" in ran.stdout and "100%" in ran.stderr, ran  # the check's summary; the progress bar


def check_sweep_parquet(ran: Ran) -> None:
    import pyarrow.parquet

    ok(ran)
    assert ran.written == {"table.parquet"}, ran.written
    table = pyarrow.parquet.read_table(ran.cwd / "table.parquet")
    assert table.column_names == ["plant.natural_frequency_hz", *documented_table_columns()]
    assert SWEEP_POINTS <= table.num_rows <= SWEEP_POINTS + SWEEP_REFINED and all(table.column("ok").to_pylist())
    assert "table check" in ran.stdout, ran


def check_served(ran: Ran) -> None:
    # the page at /, the docs at /docs (the README's comment), and ready
    for path, kind in (("/", "text/html"), ("/docs", "text/html"), ("/readyz", "application/json")):
        with urllib.request.urlopen(f"http://127.0.0.1:{ran.port}{path}", timeout=10) as answer:
            assert answer.status == 200 and answer.headers["content-type"].startswith(kind), path


def check_record_written(ran: Ran) -> None:
    ok(ran)
    assert ran.written == {"record.csv"}, ran.written
    header, *rows = csv_rows((ran.cwd / "record.csv").read_text())
    assert header == ["time_s", "accel_x", "accel_y", "accel_z"] and len(rows) == 4000


def check_identify_answer(ran: Ran) -> None:
    answered(ran, "application/json")
    answer = ran.json()
    listing = documented_identification_answer()
    assert list(listing) == list(answer)  # "shortened": every block of the answer is listed
    matches_listing(listing, answer)


def check_mkdocs_serve(ran: Ran) -> None:
    assert ran.returncode == 0, ran
    assert "<title>vibfree</title>" in ran.stdout, ran.stdout[:500]


def check_mkdocs_build(ran: Ran) -> None:
    ok(ran)
    assert {"site/index.html", "site/try-it/index.html", "site/api/index.html"} <= ran.written, ran


PYTHON_SNIPPET_CHECK = """
assert round(design.answer["metrics"]["settling_time_s"], 3) == 0.175, design.answer["metrics"]
assert table.splitlines()[0] == "time_s,position,load_position", table[:200]
assert ranking and {"stap", "time_optimal"} <= {row["family"] for row in ranking}, ranking[:1]
"""

NPZ_SNIPPET_CHECK = """
assert position.dtype == np.float64 and position.size > 100 and position[0] == 0.0
assert round(meta["metrics"]["settling_time_s"], 3) == 0.175 and "profile" not in meta
"""

DASK = "the Dask cluster is tested on a LocalCluster (tests/optim/test_sweeps.py)"

# Every command of a command block, by its first line without its comment.
COMMANDS: dict[str, Spec] = {
    # README.md and docs/index.md: two commands
    "make serve": Exempt(
        "serves until stopped; the tests' server is `vibfree serve`, the same uvicorn app with the same flags "
        "(tests/app/test_python_api.py), and `make -n serve` shows the target's recipe",
        dry_run="make -n serve",
        dry_run_says="uvicorn app.main:app",
    ),
    "make test": Exempt(
        "runs the gates and the whole suite, this test included; `make -n test` shows the target's recipe",
        dry_run="make -n test",
        dry_run_says="python -m pytest",
    ),
    # README.md and docs/try-it.md: a first design by curl
    "until curl -sf localhost:8000/readyz > /dev/null; do sleep 1; done": Run(check_readyz_loop, server=True),
    "curl -s localhost:8000/v1/profiles/pseudo-polynomial -H 'content-type: application/json' -d '{": Run(
        check_table_iii, server=True
    ),
    "curl -s localhost:8000/v1/profiles/time-optimal -H 'content-type: application/json' -d '{": Run(
        check_time_optimal_band, server=True
    ),
    "curl -s 'localhost:8000/v1/profiles/pseudo-polynomial?format=csv&columns=position,velocity,load_position'": Run(
        check_table_iii_csv, server=True
    ),
    # README.md and docs/cli-and-python.md: the command line
    "vibfree --help": Run(check_help),
    "vibfree design stap request.json --csv out.csv": Run(check_design_stap_csv),
    "vibfree design time-optimal request.json --json -": Run(check_design_json),
    "vibfree design stap request.json --csv out.csv --columns all --comments --url http://127.0.0.1:8000": Run(
        check_design_by_url, server=True
    ),
    "vibfree compare request.json": Run(check_compare),
    "vibfree identify record.csv --displacement 0.12 --max-velocity 0.5 --max-acceleration 10": Run(check_identify),
    "vibfree sweep sweep.json --out table.csv": Run(check_sweep_table, extras=("cli",)),
    "vibfree serve --port 8000 --processes 2": IsTheServer(
        check_served,
        "the tests' server runs it (tests/app/server.py) on a free port with one process and one solver worker: "
        "two processes' four workers take ~35 s to warm up on this machine",
    ),
    # README.md and docs/cli-and-python.md: from Python
    "from vibfree import compare, synthesize": Run(ok, python_check=PYTHON_SNIPPET_CHECK),
    # docs/api.md: an npz answer
    "import io": Run(ok, server=True, python_check=NPZ_SNIPPET_CHECK),
    # docs/identification.md
    "python3 - <<'EOF'": Run(check_record_written),
    "curl -s -X POST 'http://localhost:8000/v1/identify?displacement=0.05&max_velocity=0.5&max_acceleration=5'": Run(
        check_identify_answer, server=True, needs=("python3 - <<'EOF'",)
    ),
    # docs/sweeps.md: a Dask cluster
    "pip install 'vibfree[dask]'": Exempt(
        "installs from the package index; tests/test_packaging.py checks the extra, the tests' environment has it"
    ),
    "dask scheduler": Exempt(f"a Dask scheduler, serving until stopped; {DASK}"),
    "dask worker tcp://<host>:8786 --nthreads 1 --nworkers 8": Exempt(f"needs a scheduler's address; {DASK}"),
    "make serve && .venv/bin/pip install -e '.[dask]'": Exempt(
        "make serve serves until stopped, and pip install reaches the package index"
    ),
    "VIBFREE_DASK_SCHEDULER=tcp://<host>:8786 make serve": Exempt(
        f"needs a scheduler's address, and make serve serves until stopped; {DASK}, and a server given "
        "VIBFREE_DASK_SCHEDULER without the extra in tests/test_packaging.py"
    ),
    # docs/sweeps.md: vibfree sweep
    "vibfree sweep sweep.json --out table.parquet --url http://127.0.0.1:8000": Run(
        check_sweep_parquet, server=True, extras=("parquet",)
    ),
    # README.md: the documentation site
    ".venv/bin/mkdocs serve -a 127.0.0.1:8001": Run(check_mkdocs_serve, extras=("test",), background="/"),
    ".venv/bin/mkdocs build --strict": Run(check_mkdocs_build, extras=("test",)),
}


# --- the tests ---------------------------------------------------------------------------------------------------


def test_every_block_says_what_it_is():
    # A block without a language (or with another) could be commands nobody runs.
    unknown = [str(b) for b in blocks() if b.language not in COMMAND_LANGUAGES | DATA_LANGUAGES]
    assert not unknown, f"fence these as {sorted(COMMAND_LANGUAGES)} (commands) or {sorted(DATA_LANGUAGES)}"
    assert {b.language for b in blocks()} >= {"sh", "python", "text", "json"}


def test_data_blocks_hold_no_commands():
    command = re.compile(r"^\s*(\$ |curl |vibfree |python3? |pip |make |docker |kubectl |\.venv/)", re.M)
    suspicious = [str(b) for b in blocks() if b.language in DATA_LANGUAGES and command.search(b.body)]
    assert not suspicious, "a command fenced as data: fence it as sh (and list it in COMMANDS)"


def test_every_command_is_run_or_exempt():
    found = {key(c) for body, places in command_blocks().items() for c in commands(body, places[0].language)}
    missing = sorted(found - set(COMMANDS))
    assert not missing, f"new commands: add each to COMMANDS, with its check or the reason it cannot run: {missing}"
    stale = sorted(set(COMMANDS) - found)
    assert not stale, f"COMMANDS lists commands that no document has any more: {stale}"


def test_the_readme_python_snippet_imports_only_what_pip_install_installs():
    # Issue 24: the README's snippet runs after make serve, which installs no test dependency (pandas).
    hidden = set(hidden_modules().split(","))
    assert {"pandas", "pytest", "tqdm", "pyarrow", "dask", "httpx2", "mkdocs"} <= hidden
    assert not hidden & {"numpy", "scipy", "casadi", "fastapi", "uvicorn", "pydantic", "orjson", "vibfree"}
    (snippet,) = [b.body for b in blocks() if b.document == "README.md" and b.language == "python"]
    assert isinstance(COMMANDS[key(snippet)], Run)


@pytest.fixture(scope="module")
def runs(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Runs]:
    selected = [
        item.callspec.params["body"]
        for item in request.session.items
        if getattr(item, "originalname", "") == "test_command_block" and hasattr(item, "callspec")
    ]
    started = Runs(tmp_path_factory.mktemp("docs-commands"), selected)
    try:
        yield started
    finally:
        started.close()


BODIES = command_blocks()


@pytest.mark.parametrize("body", list(BODIES), ids=[", ".join(str(b) for b in BODIES[body]) for body in BODIES])
def test_command_block(body: str, runs: Runs):
    for command, spec, ran in runs.result(body):
        assert spec is not None, f"not in COMMANDS: {key(command)!r}"
        if isinstance(spec, Exempt):
            assert spec.reason
            if spec.dry_run:
                assert ran is not None and ran.returncode == 0 and spec.dry_run_says in ran.stdout, ran
        else:
            assert ran is not None
            spec.check(ran)
