"""Observability: JSON logs, request ids, Prometheus metrics and the security headers of every response.

- ``configure_logging()`` (``app.json_logs``) makes every log line one JSON object on stderr (structlog, and
  the stdlib records of ``app.*``, ``optim.*``, ``models.*`` and uvicorn through structlog's
  ``ProcessorFormatter``).
- ``install(app)`` gives the app its own Prometheus registry (``app.service_metrics.ServiceMetrics``, in
  ``app.state.metrics``) and wraps the whole ASGI stack in ``ObservabilityMiddleware``: a request id, one
  access line, the request metrics and the security headers (``app.security_headers``) on every response
  (problems, 500s and static files included).
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
import contextvars
import re
import time
import uuid
from collections.abc import Iterable
from typing import Any

import structlog
from fastapi import FastAPI
from starlette.datastructures import MutableHeaders
from starlette.routing import BaseRoute, Match, Router
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.security_headers import CONTENT_SECURITY_POLICY, SECURITY_HEADERS
from app.service_metrics import ServiceMetrics

METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"})
UNMATCHED = "unmatched"

access_log = structlog.stdlib.get_logger("app.access")
solve_log = structlog.stdlib.get_logger("app.solves")

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
