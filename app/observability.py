"""Observability: JSON logs, request ids, Prometheus metrics and the security headers of every response.

- ``configure_logging()`` makes every log line one JSON object on stderr (structlog, and the stdlib
  records of ``app.*``, ``optim.*``, ``models.*`` and uvicorn through structlog's ``ProcessorFormatter``).
- ``install(app)`` gives the app its own Prometheus registry (``app.state.metrics``) and wraps the
  whole ASGI stack in ``ObservabilityMiddleware``: a request id, one access line, the request
  metrics and the security headers on every response (problems, 500s and static files included).
- ``record_solve(...)`` logs one design run by the service layer and counts it.

With several HTTP processes (``VIBFREE_PROCESSES``, uvicorn ``--workers``) a scrape lands on any one of
them, so the metrics use prometheus_client's multiprocess mode whenever ``PROMETHEUS_MULTIPROC_DIR`` is
set (``vibfree serve`` and ``make serve`` set it to a fresh directory per server start): every process
writes its counters and histograms to that directory and a scrape sums them, dead processes' included
(https://prometheus.github.io/client_python/multiprocess/). The pool's gauges are per process
(``multiprocess_mode="liveall"``: a ``pid`` label, live processes only; the files of a process that died
are dropped with ``mark_process_dead`` at the next scrape); its counters are summed.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import contextvars
import hashlib
import logging
import os
import re
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Mapping
from html.parser import HTMLParser
from typing import Any, TextIO

import structlog
from fastapi import FastAPI
from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, PlatformCollector, ProcessCollector
from prometheus_client import multiprocess as prometheus_multiprocess
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector
from starlette.datastructures import MutableHeaders
from starlette.routing import BaseRoute, Match, Router
from starlette.types import ASGIApp, Message, Receive, Scope, Send

# --- logging -------------------------------------------------------------------------------------

#: The service's own loggers, shown from INFO (everything else from WARNING, the root's level).
APP_LOGGERS = ("app", "optim", "runtime", "models", "vibfree")


class _StderrHandler(logging.StreamHandler):  # type: ignore[type-arg]
    """A handler writing to whatever ``sys.stderr`` is at the time of each record (test capture included)."""

    @property
    def stream(self) -> TextIO:
        return sys.stderr

    @stream.setter
    def stream(self, _value: TextIO) -> None:  # StreamHandler.__init__ assigns it
        pass


def _drop_color_message(_: Any, __: str, event_dict: structlog.typing.EventDict) -> structlog.typing.EventDict:
    event_dict.pop("color_message", None)  # uvicorn's ANSI-coloured copy of its message
    return event_dict


def _formatter() -> structlog.stdlib.ProcessorFormatter:
    """The formatter of every line: a stdlib record (foreign) or a structlog event, as one JSON object."""
    return structlog.stdlib.ProcessorFormatter(
        foreign_pre_chain=[
            structlog.contextvars.merge_contextvars,  # the request id, in the thread that logs
            structlog.stdlib.add_logger_name,
            structlog.stdlib.add_log_level,
            structlog.stdlib.ExtraAdder(),
            _drop_color_message,
            structlog.processors.TimeStamper(fmt="iso", utc=True),
        ],
        processors=[
            structlog.stdlib.ProcessorFormatter.remove_processors_meta,
            structlog.processors.format_exc_info,
            structlog.processors.JSONRenderer(),
        ],
    )


def configure_logging(level: int | str = logging.INFO) -> None:
    """One JSON object per line on stderr for structlog and stdlib loggers alike. Idempotent."""
    root = logging.getLogger()
    if not any(isinstance(h, _StderrHandler) for h in root.handlers):
        structlog.configure(
            processors=[
                structlog.contextvars.merge_contextvars,
                structlog.stdlib.filter_by_level,
                structlog.stdlib.add_logger_name,
                structlog.stdlib.add_log_level,
                structlog.stdlib.PositionalArgumentsFormatter(),
                structlog.processors.TimeStamper(fmt="iso", utc=True),
                structlog.processors.StackInfoRenderer(),
                structlog.stdlib.ProcessorFormatter.wrap_for_formatter,
            ],
            logger_factory=structlog.stdlib.LoggerFactory(),
            wrapper_class=structlog.stdlib.BoundLogger,
            cache_logger_on_first_use=True,
        )
        handler = _StderrHandler()
        handler.setFormatter(_formatter())
        root.addHandler(handler)
    logging.captureWarnings(True)  # a numpy RuntimeWarning is a JSON line too (logger py.warnings), not raw stderr
    for name in APP_LOGGERS:
        logging.getLogger(name).setLevel(level)
    # uvicorn configures its loggers (dictConfig) before it imports the app: route its error logger,
    # and its access logger when it is on (it is off with --no-access-log), through the JSON handler.
    for name in ("uvicorn", "uvicorn.error", "uvicorn.access"):
        logger = logging.getLogger(name)
        if name == "uvicorn.access" and not logger.handlers and not logger.propagate:
            continue  # disabled by --no-access-log
        logger.handlers.clear()
        logger.propagate = True


def start_worker(warm_up: Callable[[], None]) -> None:
    """A solver worker's start (run in the new process): JSON logs like the server's, then the warm-up.

    A failed warm-up is logged as one JSON line with its traceback; the process then exits and the
    pool retries with back-off.
    """
    configure_logging()
    try:
        warm_up()
    except Exception:
        logging.getLogger("app.worker").exception("solver worker warm-up failed")
        raise SystemExit(1) from None


access_log = structlog.stdlib.get_logger("app.access")
solve_log = structlog.stdlib.get_logger("app.solves")

# --- metrics -------------------------------------------------------------------------------------

LATENCY_BUCKETS_S = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0)
METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"})
UNMATCHED = "unmatched"


class PoolCollector(Collector):
    """The solver pool's state, read at scrape time from ``pool.stats()`` (skipped while it has none)."""

    GAUGES = (
        ("vibfree_pool_configured_workers", "workers", "Solver worker processes configured."),
        ("vibfree_pool_queue_depth", "queued", "Solves waiting for a worker."),
    )
    COUNTERS = (
        ("vibfree_pool_restarts", "restarts", "Worker processes replaced since start."),
        ("vibfree_pool_timeouts", "timeouts", "Solves killed at their deadline."),
        ("vibfree_pool_rejected", "rejected", "Solves refused by admission control."),
    )

    def __init__(self, pool: Callable[[], object | None]) -> None:
        self._pool = pool

    def collect(self) -> Iterable[Metric]:
        stats_of = getattr(self._pool(), "stats", None)
        if not callable(stats_of):
            return []
        try:
            stats: Mapping[str, int] = stats_of()
        except Exception:  # a scrape must not fail because the pool could not say
            logging.getLogger(__name__).exception("the solver pool's stats() failed")
            return []
        metrics: list[Metric] = []
        states = [s for s in ("ready", "busy", "starting") if s in stats]
        if states:
            workers = GaugeMetricFamily(
                "vibfree_pool_workers",
                "Solver worker processes by state (ready: warm, idle or busy).",
                labels=["state"],
            )
            for state in states:
                workers.add_metric([state], stats[state])
            metrics.append(workers)
        for name, key, doc in self.GAUGES:
            if key in stats:
                metrics.append(GaugeMetricFamily(name, doc, value=stats[key]))
        for name, key, doc in self.COUNTERS:
            if key in stats:
                metrics.append(CounterMetricFamily(name, doc, value=stats[key]))  # exposed as <name>_total
        return metrics


class ThreadsCollector(Collector):
    """The design threads' state (``runtime.threads.ThreadLane.stats()``), read at scrape time (skipped while none)."""

    GAUGES = (
        ("vibfree_threads_configured", "threads", "Design threads configured (closed-form designs and fits)."),
        ("vibfree_threads_running", "running", "Design threads computing."),
        ("vibfree_threads_queue_depth", "queued", "Designs waiting for a design thread."),
        ("vibfree_threads_held", "held", "Places reserved for requests' designs not yet submitted."),
        ("vibfree_threads_overrunning", "overrunning", "Design threads still computing past their deadline (504)."),
    )
    COUNTERS = (
        ("vibfree_threads_timeouts", "timeouts", "Designs answered 504 at their deadline."),
        ("vibfree_threads_rejected", "rejected", "Designs refused by admission control (503)."),
    )

    def __init__(self, lane: Callable[[], object | None]) -> None:
        self._lane = lane

    def collect(self) -> Iterable[Metric]:
        stats_of = getattr(self._lane(), "stats", None)
        if not callable(stats_of):
            return []
        try:
            stats: Mapping[str, int] = stats_of()
        except Exception:  # a scrape must not fail because the lane could not say
            logging.getLogger(__name__).exception("the design threads' stats() failed")
            return []
        metrics: list[Metric] = [
            GaugeMetricFamily(name, doc, value=stats[key]) for name, key, doc in self.GAUGES if key in stats
        ]
        metrics += [
            CounterMetricFamily(name, doc, value=stats[key]) for name, key, doc in self.COUNTERS if key in stats
        ]
        return metrics


class ThreadsGauges:
    """The design threads' state in the shared metrics directory (multiprocess mode), as ``PoolGauges``: gauges
    with this process's pid, counters summed. ``update(stats)`` is the lane's ``on_change`` callback (called
    from its threads: prometheus_client's values lock)."""

    def __init__(self, registry: CollectorRegistry) -> None:
        self.gauges = {
            key: Gauge(name, doc + " Per HTTP process.", multiprocess_mode="liveall", registry=registry)
            for name, key, doc in ThreadsCollector.GAUGES
        }
        self.counters = {
            key: Counter(name, doc + " Summed over the HTTP processes.", registry=registry)
            for name, key, doc in ThreadsCollector.COUNTERS
        }
        self._counted = dict.fromkeys(self.counters, 0)
        self._lock = threading.Lock()

    def update(self, stats: Mapping[str, int]) -> None:
        for key, gauge in self.gauges.items():
            gauge.set(stats.get(key, 0))
        with self._lock:
            for key, counter in self.counters.items():
                delta = stats.get(key, 0) - self._counted[key]
                if delta > 0:
                    counter.inc(delta)
                    self._counted[key] += delta


def multiprocess_dir() -> str | None:
    """The shared metrics directory of a multi-process server, or None (one process: in-memory metrics)."""
    return os.environ.get("PROMETHEUS_MULTIPROC_DIR") or None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, another user's
        return True
    return True


_LIVE_FILE = re.compile(r"gauge_live\w+?_(\d+)\.db")


def forget_dead_processes(path: str) -> list[int]:
    """``mark_process_dead`` for every process whose live-gauge files are in ``path`` but which is gone
    (a process killed without its shutdown); its counters stay in the sums. Returns their pids."""
    dead = set()
    with contextlib.suppress(OSError):
        for name in os.listdir(path):
            match = _LIVE_FILE.fullmatch(name)
            if match and not _alive(int(match.group(1))):
                dead.add(int(match.group(1)))
    for pid in dead:
        prometheus_multiprocess.mark_process_dead(pid, path)  # type: ignore[no-untyped-call]
    return sorted(dead)


class PoolGauges:
    """The pool's state in the shared metrics directory (multiprocess mode): gauges with this process's
    pid, counters summed over processes. ``update(stats)`` is the pool's ``on_change`` callback."""

    STATES = ("ready", "busy", "starting")

    def __init__(self, registry: CollectorRegistry) -> None:
        self.workers = Gauge(
            "vibfree_pool_workers",
            "Solver worker processes by state (ready: warm, idle or busy), per HTTP process.",
            ["state"],
            multiprocess_mode="liveall",
            registry=registry,
        )
        self.gauges = {
            key: Gauge(name, doc + " Per HTTP process.", multiprocess_mode="liveall", registry=registry)
            for name, key, doc in PoolCollector.GAUGES
        }
        self.counters = {
            key: Counter(name, doc + " Summed over the HTTP processes.", registry=registry)
            for name, key, doc in PoolCollector.COUNTERS
        }
        self._counted = dict.fromkeys(self.counters, 0)

    def update(self, stats: Mapping[str, int]) -> None:
        for state in self.STATES:
            self.workers.labels(state).set(stats.get(state, 0))
        for key, gauge in self.gauges.items():
            gauge.set(stats.get(key, 0))
        for key, counter in self.counters.items():
            delta = stats.get(key, 0) - self._counted[key]
            if delta > 0:
                counter.inc(delta)
                self._counted[key] += delta


def processes_state(path: str) -> dict[int, dict[str, int]]:
    """Each live HTTP process's pool state as the shared directory has it: pid -> {ready, busy, starting,
    queued, workers} (for /readyz: a probe lands on one process and answers for all)."""
    forget_dead_processes(path)
    registry = CollectorRegistry()
    prometheus_multiprocess.MultiProcessCollector(registry, path)  # type: ignore[no-untyped-call]
    out: dict[int, dict[str, int]] = {}
    keys = {"vibfree_pool_queue_depth": "queued", "vibfree_pool_configured_workers": "workers"}
    for metric in registry.collect():
        for sample in metric.samples:
            pid = sample.labels.get("pid")
            if pid is None:
                continue
            if sample.name == "vibfree_pool_workers":
                out.setdefault(int(pid), {})[sample.labels["state"]] = int(sample.value)
            elif sample.name in keys:
                out.setdefault(int(pid), {})[keys[sample.name]] = int(sample.value)
    return out


class ServiceMetrics:
    """One app's metrics, in a registry of its own (an app factory may run several times in a process).

    In multiprocess mode (``multiprocess_dir()``) the values also go to the shared directory, and
    ``scrape_registry()`` reads every process's; the pool's state is written by ``pool_gauges.update``."""

    def __init__(self, pool: Callable[[], object | None], threads: Callable[[], object | None] = lambda: None) -> None:
        self.multiprocess_dir = multiprocess_dir()
        self.registry = CollectorRegistry()
        self.requests = Counter(
            "vibfree_http_requests",
            "HTTP requests by method, route template (or 'unmatched') and status.",
            ["method", "route", "status"],
            registry=self.registry,
        )
        self.latency = Histogram(
            "vibfree_http_request_duration_seconds",
            "Time from the request to the last byte of the response, by route template.",
            ["route"],
            buckets=LATENCY_BUCKETS_S,
            registry=self.registry,
        )
        self.solves = Counter(
            "vibfree_solves",
            "Designs run by the service layer, by family and outcome ('ok' or the problem type).",
            ["family", "outcome"],
            registry=self.registry,
        )
        self.solve_duration = Histogram(
            "vibfree_solve_duration_seconds",
            "Wall time of one design in the service layer (waiting for a worker included), by family.",
            ["family"],
            buckets=LATENCY_BUCKETS_S,
            registry=self.registry,
        )
        self.pool_gauges: PoolGauges | None = None
        self.thread_gauges: ThreadsGauges | None = None
        if self.multiprocess_dir is None:
            self.registry.register(PoolCollector(pool))
            self.registry.register(ThreadsCollector(threads))
            ProcessCollector(registry=self.registry)
            PlatformCollector(registry=self.registry)
        else:  # custom collectors see only the answering process: the pool's state goes to the files
            self.pool_gauges = PoolGauges(self.registry)
            self.thread_gauges = ThreadsGauges(self.registry)

    def scrape_registry(self) -> CollectorRegistry:
        """What /metrics exposes: this app's registry, or in multiprocess mode every process's files."""
        if self.multiprocess_dir is None:
            return self.registry
        forget_dead_processes(self.multiprocess_dir)
        registry = CollectorRegistry()
        prometheus_multiprocess.MultiProcessCollector(registry, self.multiprocess_dir)  # type: ignore[no-untyped-call]
        return registry


# The metrics of the app serving the current request (set by the middleware), for record_solve.
_current_metrics: contextvars.ContextVar[ServiceMetrics | None] = contextvars.ContextVar(
    "vibfree_metrics", default=None
)


def record_solve(
    family: str,
    duration_s: float,
    *,
    result: Any = None,
    error: BaseException | None = None,
    executor: str = "thread",
) -> None:
    """Log one design (its family, outcome, solver status, iterations and time) and count it.

    ``result`` is an ``optim.synthesis.Result`` (its ``solver`` summary, when a solver ran); ``error``
    the exception that ended the design instead: its outcome is its problem type (``infeasible``,
    ``solver-failed``, ``solve-timeout``, ``not-ready``, ...), ``cancelled`` or ``error``.
    """
    if error is None:
        outcome = "ok"
        solver = getattr(result, "solver", None)
    elif isinstance(error, asyncio.CancelledError):
        outcome, solver = "cancelled", None
    else:
        outcome = getattr(error, "problem_type", None) or "error"
        solver = getattr(error, "report", None)
    fields: dict[str, Any] = {
        "family": family,
        "outcome": outcome,
        "executor": executor,
        "duration_ms": round(duration_s * 1e3, 3),
        "solver_status": getattr(solver, "status", None),
        "iterations": getattr(solver, "iterations", None),
        "solver_time_s": getattr(solver, "solve_time_s", None),
    }
    if solver is not None and hasattr(solver, "solves"):
        fields["solves"] = solver.solves
    if error is not None:
        fields["error"] = str(error)[:500]
        if hasattr(error, "limit_s"):
            fields["limit_s"] = error.limit_s
    if outcome in ("ok", "infeasible", "not-applicable", "invalid-input", "cancelled"):
        solve_log.info("solve", **fields)
    else:
        solve_log.warning("solve", **fields)
    metrics = _current_metrics.get()
    if metrics is not None:
        metrics.solves.labels(family, outcome).inc()
        metrics.solve_duration.labels(family).observe(duration_s)


# --- the middleware ------------------------------------------------------------------------------

REQUEST_ID_HEADER = "x-request-id"
_SANE_REQUEST_ID = re.compile(r"[A-Za-z0-9\-_.:]{1,128}")

#: The page and the API use only the service's own assets (uPlot sets styles through the CSSOM, which
#: style-src does not restrict; the page has no inline script or style).
CONTENT_SECURITY_POLICY = (
    "default-src 'self'; img-src 'self' data:; style-src 'self'; script-src 'self'; object-src 'none'; "
    "base-uri 'none'; form-action 'self'; frame-ancestors 'none'"
)
#: Swagger UI (/docs) and ReDoc (/redoc) are served from /static/vendor (no CDN host anywhere); FastAPI's
#: pages start them with inline code, which ``docs_content_security_policy`` allows by its sha256 and
#: nothing else; images are the bundles' own data: URIs. ReDoc builds its search worker from a blob: URL
#: (made by the page, fetched from nowhere), which worker-src allows. Its "API docs by Redocly" logo is
#: an <img> from cdn.redoc.ly: img-src blocks it and ReDoc drops the <img> (its onError), so nothing
#: is fetched from that host.
_DOCS_POLICY_TEMPLATE = (
    "default-src 'self'; script-src 'self'{scripts}; style-src 'self'{styles}; img-src 'self' data:; "
    "font-src 'self'; connect-src 'self'; worker-src 'self' blob:; object-src 'none'; base-uri 'none'; "
    "form-action 'self'; frame-ancestors 'none'"
)


class _InlineCode(HTMLParser):
    """The text of each inline ``<script>`` (one without ``src``) and each ``<style>`` of a page."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=False)
        self.scripts: list[str] = []
        self.styles: list[str] = []
        self._current: list[str] | None = None
        self._chunks: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "style" or (tag == "script" and "src" not in dict(attrs)):
            self._current = self.styles if tag == "style" else self.scripts
            self._chunks = []

    def handle_data(self, data: str) -> None:
        if self._current is not None:
            self._chunks.append(data)

    def handle_endtag(self, tag: str) -> None:
        if self._current is not None and tag in ("script", "style"):
            self._current.append("".join(self._chunks))
            self._current = None


def hash_source(text: str) -> str:
    """A CSP hash source: ``'sha256-<base64 of the digest of the UTF-8 text>'`` (CSP Level 3, Sec. 2.3.1)."""
    return "'sha256-" + base64.b64encode(hashlib.sha256(text.encode()).digest()).decode() + "'"


def docs_content_security_policy(html: str, runtime_styles: Iterable[str] = ()) -> str:
    """The policy of a docs page: the service's own assets, the page's inline scripts and styles by
    their sha256, and ``runtime_styles`` (hash sources of the ``<style>`` elements its bundle adds
    at run time); no 'unsafe-inline', so no other inline code runs."""
    parser = _InlineCode()
    parser.feed(html)
    parser.close()
    scripts = dict.fromkeys(hash_source(text) for text in parser.scripts)
    styles = dict.fromkeys([*(hash_source(text) for text in parser.styles), *runtime_styles])
    return _DOCS_POLICY_TEMPLATE.format(
        scripts="".join(" " + s for s in scripts), styles="".join(" " + s for s in styles)
    )


SECURITY_HEADERS = (
    ("x-content-type-options", "nosniff"),
    ("referrer-policy", "no-referrer"),
)


def request_id_of(headers: Iterable[tuple[bytes, bytes]]) -> str:
    """The client's ``X-Request-ID`` if it is a sane token (1-128 ASCII letters, digits, ``-_.:``), else a uuid4 hex."""
    for name, value in headers:
        if name.lower() == b"x-request-id":
            candidate = value.decode("latin-1")
            if _SANE_REQUEST_ID.fullmatch(candidate):
                return candidate
            break
    return uuid.uuid4().hex


def route_template(scope: Scope, routes: Iterable[BaseRoute] = ()) -> str:
    """The path template of the route that served ``scope`` (``/problems/{slug}``, ``/static/{path}``).

    FastAPI records its own routes in ``scope["route"]``; its documentation routes and the static mount
    are found in ``routes`` by the request's method and path. Anything else is ``unmatched``.
    """
    route = scope.get("route")
    if route is None:
        probe = {"type": "http", "path": scope.get("path", ""), "root_path": "", "method": scope.get("method", "")}
        route = next((r for r in routes if r.matches(probe)[0] is not Match.NONE), None)
    template = getattr(route, "path_format", None) or getattr(route, "path", None)
    return template if isinstance(template, str) and template else UNMATCHED


def _client(scope: Scope) -> str | None:
    client = scope.get("client")
    return f"{client[0]}:{client[1]}" if client else None


class ObservabilityMiddleware:
    """Pure ASGI middleware (streaming and contextvars intact), outside every other layer.

    For each HTTP request: its id (bound in structlog's contextvars, echoed in ``X-Request-ID``), the
    security headers, no ``server`` header, the request metrics and one access line.
    """

    def __init__(self, app: ASGIApp, metrics: ServiceMetrics, router: Router | None = None) -> None:
        self.app = app
        self.metrics = metrics
        self.router = router

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = time.perf_counter()
        request_id = request_id_of(scope.get("headers", []))
        scope.setdefault("state", {})["request_id"] = request_id
        status = 500  # if the app fails before it answers

        async def send_with_headers(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
                headers = MutableHeaders(scope=message)
                headers[REQUEST_ID_HEADER] = request_id
                headers.setdefault("content-security-policy", CONTENT_SECURITY_POLICY)  # unless the route set its own
                for name, value in SECURITY_HEADERS:
                    headers.setdefault(name, value)
                if "server" in headers:
                    del headers["server"]
            await send(message)

        context = structlog.contextvars.bind_contextvars(request_id=request_id)
        metrics_token = _current_metrics.set(self.metrics)
        try:
            await self.app(scope, receive, send_with_headers)
        finally:
            duration_s = time.perf_counter() - started
            route = route_template(scope, self.router.routes if self.router is not None else ())
            method = scope.get("method", "")
            self.metrics.requests.labels(method if method in METHODS else "other", route, str(status)).inc()
            self.metrics.latency.labels(route).observe(duration_s)
            (access_log.warning if status >= 500 else access_log.info)(
                "request",
                method=method,
                path=scope.get("path"),
                route=route,
                status=status,
                duration_ms=round(duration_s * 1e3, 3),
                request_id=request_id,
                client=_client(scope),
            )
            _current_metrics.reset(metrics_token)
            structlog.contextvars.reset_contextvars(**context)


def install(app: FastAPI) -> ServiceMetrics:
    """Give ``app`` its metrics (``app.state.metrics``) and wrap its whole middleware stack.

    The wrapper goes outside Starlette's ``ServerErrorMiddleware`` (which ``add_middleware`` cannot
    do), so that a 500 problem carries the request id and the security headers too.
    """
    metrics = ServiceMetrics(lambda: getattr(app.state, "pool", None), lambda: getattr(app.state, "threads", None))
    app.state.metrics = metrics
    build_stack = app.build_middleware_stack

    def build_middleware_stack() -> ASGIApp:
        return ObservabilityMiddleware(build_stack(), metrics, app.router)

    app.build_middleware_stack = build_middleware_stack  # type: ignore[method-assign]
    return metrics
