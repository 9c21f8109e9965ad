"""The Python API: the family endpoints, compare and sweeps, in-process, over the service's own pipeline.

The same request schemas validate the request, the same service layer (``app.services``) runs it, on an
``InlineExecutor`` instead of the solver pool (one caller owns the process, so IPOPT runs here), and the
same code writes the CSV. An error is a ``VibfreeError`` holding the problem+json the HTTP service answers.
"""

from __future__ import annotations

import asyncio
import os
import threading
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import orjson
import structlog
from pydantic import ValidationError

from app import problems
from app.encoding import dumps
from app.family_names import name_of, slug_of
from app.responses import comment_lines, csv_body, drop_duplicates
from app.schemas.compare import CompareIn
from app.schemas.family import ProfileRequest
from app.schemas.registry import (
    REQUEST_SCHEMAS as REQUEST_SCHEMAS,  # vibfree.REQUEST_SCHEMAS: family name -> request schema
)
from app.services import compare as compare_service
from app.services import profile as profiles
from app.settings import Settings, get_settings
from models.errors import DomainError
from optim import registry, tables
from optim.synthesis import Result
from runtime.executor import InlineExecutor


def _route_logs_to_stdlib() -> None:
    """On the first call (not on import): unless the caller configured structlog, the service's log lines go to
    stdlib logging, whose configuration (the caller's) decides what is shown."""
    if not structlog.is_configured():
        structlog.configure(
            processors=[structlog.stdlib.filter_by_level, structlog.stdlib.render_to_log_kwargs],
            logger_factory=structlog.stdlib.LoggerFactory(),
            wrapper_class=structlog.stdlib.BoundLogger,
        )


def __getattr__(name: str) -> Any:
    if name == "FAMILIES":  # the old name of REQUEST_SCHEMAS (family name -> request schema)
        warnings.warn(
            "vibfree.api.FAMILIES is deprecated: use vibfree.api.REQUEST_SCHEMAS", DeprecationWarning, stacklevel=2
        )
        return REQUEST_SCHEMAS
    raise AttributeError(f"module 'vibfree.api' has no attribute {name!r}")


class VibfreeError(Exception):
    """A request the service would refuse: ``problem`` is its problem+json body (type, title, status, detail,
    field, errors)."""

    def __init__(self, problem: dict[str, Any]) -> None:
        self.problem = problem
        self.status = int(problem.get("status", 500))
        super().__init__(f"{problem.get('title', 'error')}: {problem.get('detail', '')}")

    def __reduce__(self) -> tuple[Any, ...]:  # from a batch's worker process: rebuilt from its problem
        return (type(self), (self.problem,))


@dataclass(frozen=True)
class Synthesis:
    """One design: ``answer`` is the JSON answer of the family endpoint (numpy arrays for the series),
    ``result`` the pipeline's result it was made from."""

    family: str
    request: ProfileRequest
    answer: dict[str, Any]
    result: Result = field(repr=False)

    def json(self) -> bytes:
        """The answer as the endpoint's JSON bytes."""
        return dumps(self.answer)

    def csv(self, columns: Iterable[str] | None = None, comments: bool = False) -> str:
        """The cam table of ``?format=csv[&columns=...][&comments=true]``: t_k = k * sample period exactly."""
        names = tables.PROFILE_COLUMNS if columns is None else tuple(columns)
        table = _guard(lambda: tables.table(self.result, names))
        lines = comment_lines(_title(self.family), self.request, self.answer, table) if comments else []
        return csv_body(table, lines).decode()


def synthesize(family: str, request: Mapping[str, Any] | str | bytes, *, settings: Settings | None = None) -> Synthesis:
    """Design ``family``'s command for ``request`` (a dict, or its JSON text), as ``POST /v1/profiles/<family>``."""
    name, model = _family(family)
    body = _validate(model, request)
    design = profiles.design(registry.FAMILIES[name], body, settings or get_settings(), InlineExecutor())
    answer, result = _run_inline(design)
    return Synthesis(name, body, drop_duplicates(answer), result)  # as the endpoint answers (no load.time_s)


def synthesize_many(
    family: str,
    requests: Iterable[Mapping[str, Any] | str | bytes],
    *,
    settings: Settings | None = None,
    processes: int = 1,
) -> list[Synthesis | VibfreeError]:
    """Design ``family``'s command for each request, in order: a batch of moves (a machine planning its cycle). A
    request the service would refuse gives its ``VibfreeError`` in its place, so one bad move does not lose the
    others. ``processes``: 1 designs them here, one after the other, on one event loop; more (up to the cores this
    process may use: more would only compete for them) spread chunks of consecutive moves over that many worker
    processes (vibfree.batch), with the same answers."""
    name, _ = _family(family)
    chosen = settings or get_settings()
    processes = _processes(processes)
    if processes == 1:
        return _designs(name, requests, chosen)
    from vibfree.batch import in_processes

    return in_processes(_designs, name, list(requests), chosen, processes)


def _designs(
    name: str, requests: Iterable[Mapping[str, Any] | str | bytes], settings: Settings
) -> list[Synthesis | VibfreeError]:
    """The serial batch (each process of a parallel one runs it on its chunk)."""
    model = REQUEST_SCHEMAS[name]

    async def each() -> list[Synthesis | VibfreeError]:
        out: list[Synthesis | VibfreeError] = []
        for request in requests:
            try:
                body = _validate(model, request)
                answer, result = await profiles.design(registry.FAMILIES[name], body, settings, InlineExecutor())
            except VibfreeError as exc:
                out.append(exc)
            except DomainError as exc:
                out.append(VibfreeError(orjson.loads(problems.domain_problem(exc).body)))
            else:
                out.append(Synthesis(name, body, drop_duplicates(answer), result))
        return out

    designs: list[Synthesis | VibfreeError] = _run_inline(each())
    return designs


def compare(request: Mapping[str, Any] | str | bytes, *, settings: Settings | None = None) -> dict[str, Any]:
    """Every family on one plant, move and limits, as ``POST /v1/compare`` (its JSON answer)."""
    body = _validate(CompareIn, request)
    answer: dict[str, Any] = _run(compare_service.answer(body, settings or get_settings(), InlineExecutor()))
    return answer


def identify(record: str | bytes, *, settings: Settings | None = None, **params: Any) -> dict[str, Any]:
    """The modes of a measured record (CSV text: a header, a time column, signal columns) and, given the move
    and limits (``displacement`` or ``target_velocity``, ``max_velocity``, ``max_acceleration``, ``max_jerk``),
    the recommended design, as ``POST /v1/identify`` with ``text/csv`` (its JSON answer). The candidates run
    here, one after the other."""
    from app.schemas.identify import MeasurementParams
    from app.services.identify import identify_csv, in_process_runner

    settings = settings or get_settings()
    text = record.decode() if isinstance(record, bytes) else record
    query = _validate(MeasurementParams, params)
    coroutine = identify_csv(text, query, in_process_runner(settings), max_rows=settings.identify_max_rows)
    answer: dict[str, Any] = _run(coroutine)
    return answer


@dataclass(frozen=True)
class ProgramAnswer:
    """A machine program's answer (``answer``: the JSON of ``POST /v1/programs``) and its cam table (``csv()``)."""

    answer: dict[str, Any] = field(repr=False)
    result: Any = field(repr=False)  # optim.programs.ProgramResult

    def csv(self) -> str:
        """The cam table, as ``?format=csv``: time_s and each axis's motor position at t_k = k * period."""
        from app.services.programs import cam_text

        return cam_text(self.result)


def program(
    request: Mapping[str, Any] | str | bytes, *, settings: Settings | None = None, processes: int = 1
) -> ProgramAnswer:
    """A machine program (several axes, a cycle of moves), as ``POST /v1/programs``. ``processes``: 1 designs the
    moves here, one after the other; more (up to the cores this process may use) design them in that many worker
    processes at once (vibfree.batch: run the call under ``if __name__ == "__main__":``), with the same answer."""
    from app.schemas.programs import ProgramIn
    from app.services import programs as program_service

    body = _validate(ProgramIn, request)
    chosen = settings or get_settings()
    count = _processes(processes)
    if count == 1:
        answer, result = _run(program_service.answer(body, chosen, InlineExecutor()))
        return ProgramAnswer(answer, result)
    from vibfree.batch import ProcessesExecutor

    pool = ProcessesExecutor(count)
    answer, result = _run(program_service.answer(body, chosen, pool, capacity=2 * count, assembler=InlineExecutor()))
    return ProgramAnswer(answer, result)


def _processes(processes: object) -> int:
    """``processes`` checked: an integer from 1 to the cores this process may use (more would only compete)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    if isinstance(processes, bool) or not isinstance(processes, int) or not 1 <= processes <= cores:
        detail = f"must be an integer from 1 to the {cores} cores this process may use, got {processes!r}"
        raise VibfreeError(_problem("invalid-input", detail, "processes"))
    return processes


@dataclass(frozen=True)
class Sweep:
    """A design sweep's NDJSON lines, as ``POST /v1/sweeps`` streams them (``line``: row, check, summary)."""

    lines: list[dict[str, Any]] = field(repr=False)

    @property
    def rows(self) -> list[dict[str, Any]]:
        """One per point, sorted by index."""
        return sorted((x for x in self.lines if x["line"] == "row"), key=lambda r: int(r["index"]))

    @property
    def checks(self) -> list[dict[str, Any]]:
        return [x for x in self.lines if x["line"] == "check"]

    @property
    def summary(self) -> dict[str, Any]:
        return next(x for x in self.lines if x["line"] == "summary")

    def table(self) -> list[dict[str, Any]]:
        """One flat row per point (the axes' values, then the numbers): what ``vibfree sweep --out`` writes."""
        from vibfree.sweep_table import flat_rows

        return flat_rows(self.lines)


def sweep(
    request: Mapping[str, Any] | str | bytes,
    *,
    settings: Settings | None = None,
    scheduler: str | None = None,
    on_line: Callable[[dict[str, Any]], None] | None = None,
) -> Sweep:
    """One family's design across a grid of requests, and the table check, as ``POST /v1/sweeps`` (its lines).

    The points run here, one after the other, or on the Dask cluster at ``scheduler`` (default: the setting
    ``VIBFREE_DASK_SCHEDULER``); ``on_line`` sees each line as it comes (a progress bar)."""
    from app.schemas.sweeps import SweepIn
    from app.services.sweeps import SweepPlan, executor_for, lines

    body = _validate(SweepIn, request)
    settings = settings or get_settings()
    address = scheduler or settings.dask_scheduler

    async def run() -> list[dict[str, Any]]:
        plan = SweepPlan(body, settings)
        out: list[dict[str, Any]] = []
        async with executor_for(address, InlineExecutor(), 1) as (executor, capacity):
            async for line in lines(plan, executor, capacity):
                out.append(line)
                if on_line is not None:
                    on_line(line)
        return out

    try:
        return Sweep(_run(run()))
    except problems.InvalidRequestBody as exc:
        response = problems.invalid_input(problems.validation_errors(exc.errors), total=len(exc.errors))
        raise VibfreeError(orjson.loads(response.body)) from None


def _family(family: str) -> tuple[str, type[ProfileRequest]]:
    name = name_of(family)
    if name not in REQUEST_SCHEMAS:
        raise VibfreeError(
            _problem("not-found", f"no family {family!r}; one of {', '.join(REQUEST_SCHEMAS)}", "family")
        )
    return name, REQUEST_SCHEMAS[name]


def _title(family: str) -> str:
    return f"{slug_of(family)} profile"


def _validate(model: type[Any], request: Mapping[str, Any] | str | bytes) -> Any:
    try:
        data = orjson.loads(request) if isinstance(request, str | bytes) else dict(request)
    except orjson.JSONDecodeError as exc:
        raise VibfreeError(_problem("malformed-body", f"the request is not valid JSON ({exc})")) from None
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        response = problems.invalid_input(problems.validation_errors(exc.errors()), total=len(exc.errors()))
        raise VibfreeError(orjson.loads(response.body)) from None


_LOOP: tuple[int, asyncio.AbstractEventLoop] | None = None  # (the process that started it, the loop)
_LOOP_LOCK = threading.Lock()


def _loop() -> asyncio.AbstractEventLoop:
    """The API's own event loop, running in a daemon thread for the life of the process: asyncio.run per call
    spent 0.2 s closing its loop (joining the worker thread that parsed the request), as long as a whole design.
    A forked child starts its own (the parent's thread does not exist there)."""
    global _LOOP
    with _LOOP_LOCK:
        if _LOOP is None or _LOOP[0] != os.getpid():
            loop = asyncio.new_event_loop()
            threading.Thread(target=loop.run_forever, name="vibfree-api-loop", daemon=True).start()
            _LOOP = (os.getpid(), loop)
        return _LOOP[1]


_TURN = threading.Lock()  # one API call at a time in this process: IPOPT is not thread-safe


def _fresh_turn() -> None:
    global _TURN
    _TURN = threading.Lock()  # a child forked while another thread held it would wait forever


if hasattr(os, "register_at_fork"):  # (POSIX)
    os.register_at_fork(after_in_child=_fresh_turn)


def _run(coroutine: Any) -> Any:
    """The coroutine's result, run on the API's event loop (its own thread: the caller may run a loop of its own,
    a notebook or an async caller). Calls from several threads take turns (``_TURN``), as IPOPT needs."""
    _route_logs_to_stdlib()
    turn = _TURN  # (the lock this call takes: a fork replaces the module's)
    turn.acquire()
    try:
        future = asyncio.run_coroutine_threadsafe(coroutine, _loop())
    except BaseException:
        turn.release()
        raise
    future.add_done_callback(lambda _: turn.release())  # when the coroutine ends, not when the wait for it does (a
    return _guard(future.result)  # Ctrl-C in the caller leaves it running on the loop, still holding the turn)


def _run_inline(coroutine: Any) -> Any:
    """The result of a coroutine whose every await completes at once (a design on an ``InlineExecutor``: nothing
    is awaited but the executor's inline ``run``), run to its end in the calling thread: the hop to the API's loop
    thread and back cost 0.3-0.5 ms of a 3 ms time-optimal design (its data and code cold on the other core).
    Calls from several threads take turns with every other (``_TURN``)."""
    _route_logs_to_stdlib()
    with _TURN:
        return _guard(lambda: _to_the_end(coroutine))


def _to_the_end(coroutine: Any) -> Any:
    try:
        coroutine.send(None)
    except StopIteration as done:
        return done.value
    coroutine.close()
    raise RuntimeError("an inline design awaited something that does not complete at once: run it with _run")


def _guard(call: Any) -> Any:
    try:
        return call()
    except DomainError as exc:
        raise VibfreeError(orjson.loads(problems.domain_problem(exc).body)) from None


def _problem(slug: str, detail: str, field: str | None = None) -> dict[str, Any]:
    return orjson.loads(problems.render_problem(slug, detail, field=field)[1])  # type: ignore[no-any-return]
