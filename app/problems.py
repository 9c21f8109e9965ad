"""RFC 9457 problem details: every error the service returns is ``application/problem+json``.

Each problem has its own ``type`` (a path under ``/problems/`` that the service documents), a
``title``, the HTTP ``status``, a ``detail`` sentence and, where one field is at fault, ``field``.
Invalid input lists every broken rule in ``errors`` with the field, the value and the rule.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Coroutine
from typing import Any

import orjson
from fastapi import APIRouter, FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.responses import Response
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.encoding import dumps
from models.errors import DomainError, Infeasible, InvalidParameter, NotApplicable, PoolUnavailable, SolverFailed
from models.plants import PLANT_KINDS

log = logging.getLogger(__name__)
PROBLEM_MEDIA_TYPE = "application/problem+json"

# slug -> (status, title, what it means); served at /problems/{slug}
PROBLEM_TYPES: dict[str, tuple[int, str, str]] = {
    "invalid-input": (422, "Invalid input", "A field breaks a rule: see errors[] for each field, value and rule."),
    "infeasible": (422, "Infeasible limits", "No design can meet the requested limits; detail says why."),
    "not-applicable": (422, "Family not applicable", "The family cannot design this move; detail says why."),
    "solver-failed": (422, "Solver failed", "The optimiser stopped without a valid design; no profile is returned."),
    "solve-timeout": (504, "Solve timed out", "The solve overran its time limit; no profile is returned."),
    "not-ready": (503, "Service not ready", "The solver workers are starting or restarting; retry after Retry-After."),
    "busy": (
        503,
        "Service busy",
        "Every solver worker is busy and the queue is full (VIBFREE_MAX_QUEUED), or no worker became free within "
        "the solve's deadline; retry after Retry-After seconds.",
    ),
    "malformed-body": (400, "Malformed body", "The body cannot be parsed: it is not valid JSON (or not UTF-8)."),
    "unsupported-media-type": (
        415,
        "Unsupported media type",
        "The body must be JSON: send content-type application/json (or application/*+json); POST /v1/identify also "
        "takes text/csv.",
    ),
    "body-too-large": (413, "Request body too large", "The body exceeds the configured size limit."),
    "not-found": (404, "Not found", "No such path."),
    "method-not-allowed": (405, "Method not allowed", "The path does not accept this method."),
    "not-acceptable": (406, "Not acceptable", "The requested representation is not offered."),
    "internal-error": (500, "Internal error", "An unexpected error; it is logged. Please report it."),
}


class FieldError(BaseModel):
    field: str = Field(description="Dotted path of the field, e.g. plant.damping_ratio or profile.time_s[3].")
    value: Any = Field(None, description="The value received (long arrays are summarised).")
    rule: str = Field(description="The rule the value breaks.")


class ProblemDetails(BaseModel):
    """RFC 9457 problem details."""

    model_config = ConfigDict(extra="allow")
    type: str = Field(description="URI reference of the problem type, documented at that path.")
    title: str
    status: int
    detail: str
    field: str | None = Field(None, description="The field at fault, when there is one.")
    errors: list[FieldError] | None = Field(None, description="Every broken rule, for invalid input.")


class ProblemError(Exception):
    """Raise to answer with a problem of a given type."""

    def __init__(self, slug: str, detail: str, *, field: str | None = None, **extra: Any) -> None:
        self.slug = slug
        self.detail = detail
        self.field = field
        self.extra = extra
        super().__init__(detail)


# The largest problem body: echoed values, rules and details are truncated to fit, and ``errors``
# beyond the budget are dropped (``errors_omitted`` counts them).
PROBLEM_MAX_BYTES = 16 * 1024
MAX_ECHO_CHARS = 200  # an echoed string value
MAX_TEXT_CHARS = 1000  # a detail or a rule
MAX_ECHO_ITEMS = 8  # a list echoed in full
MAX_ECHO_KEYS = 16  # an object echoed in part
MAX_ECHO_DEPTH = 3
RETRY_AFTER_S = 5  # every 503 says when to come back (a PoolUnavailable gives its own estimate)
_INT_BITS = 63  # orjson writes 64-bit integers only


def safe_text(text: str, limit: int = MAX_TEXT_CHARS) -> str:
    """``text`` cut to ``limit`` characters, with lone surrogates (which no JSON encoder writes) escaped."""
    if len(text) > limit:
        text = text[:limit] + "..."
    return text.encode("utf-8", "backslashreplace").decode("utf-8")


def summarise(value: Any, depth: int = 0) -> Any:
    """A value small enough to echo back, and always serialisable: long strings and lists are cut or
    described, huge integers and bytes become text, NaN and infinities their names."""
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, int):
        if value.bit_length() <= _INT_BITS:
            return value
        return f"an integer of {value.bit_length()} bits"
    if isinstance(value, float):
        if value != value:
            return "NaN"
        if value in (float("inf"), float("-inf")):
            return "Infinity" if value > 0 else "-Infinity"
        return value
    if isinstance(value, str):
        return safe_text(value, MAX_ECHO_CHARS)
    if isinstance(value, bytes | bytearray | memoryview):
        raw = bytes(value[: MAX_ECHO_CHARS + 1])
        return safe_text(f"{len(value)} bytes: {raw!r}", MAX_ECHO_CHARS)
    if isinstance(value, list | tuple):
        if len(value) > MAX_ECHO_ITEMS or depth >= MAX_ECHO_DEPTH:
            return f"list of {len(value)} items"
        return [summarise(v, depth + 1) for v in value]
    if isinstance(value, dict):
        if depth >= MAX_ECHO_DEPTH:
            return f"object of {len(value)} fields"
        items = list(value.items())[:MAX_ECHO_KEYS]
        return {safe_text(str(k), MAX_ECHO_CHARS): summarise(v, depth + 1) for k, v in items}
    return safe_text(repr(value), MAX_ECHO_CHARS)


def _safe_error(error: dict[str, Any]) -> dict[str, Any]:
    return {
        "field": safe_text(str(error.get("field", "body")), MAX_ECHO_CHARS),
        "value": summarise(error.get("value")),
        "rule": safe_text(str(error.get("rule", "invalid"))),
    }


def render_problem(slug: str, detail: str, *, field: str | None = None, **extra: Any) -> tuple[int, bytes]:
    """The status and body of a problem: never fails, never above ``PROBLEM_MAX_BYTES``.

    Every echoed part is made safe (``summarise``, ``safe_text``); if the body is still above the
    budget, the ``errors`` that do not fit are dropped, then every extra member."""

    status, title, _ = PROBLEM_TYPES[slug]
    head: dict[str, Any] = {"type": f"/problems/{slug}", "title": title, "status": status}
    head["detail"] = safe_text(str(detail))
    if field is not None:
        head["field"] = safe_text(str(field), MAX_ECHO_CHARS)
    errors = extra.pop("errors", None)
    rest = {safe_text(str(k), MAX_ECHO_CHARS): summarise(v) for k, v in extra.items()}
    try:
        body = dumps({**head, **rest})
        if len(body) > PROBLEM_MAX_BYTES:
            raise ValueError("too large")
    except (TypeError, ValueError):  # orjson.JSONEncodeError is a TypeError
        rest, body = {}, dumps(head)
    if errors is None:
        return status, body
    safe = [_safe_error(e) for e in errors]
    kept: list[dict[str, Any]] = []
    # each error costs its own size plus a comma; the members around them about 64 bytes
    budget = PROBLEM_MAX_BYTES - len(body) - 64
    for error in safe:
        size = len(dumps(error)) + 1
        if size > budget:  # a value too large to echo: the field and the rule still help
            error = {**error, "value": "(too large to echo)"}
            size = len(dumps(error)) + 1
        if size > budget:
            break
        kept.append(error)
        budget -= size
    full: dict[str, Any] = {**head, **rest, "errors": kept}
    if len(kept) < len(safe):
        full["errors_omitted"] = len(safe) - len(kept)
    return status, dumps(full)


def problem_response(slug: str, detail: str, *, field: str | None = None, **extra: Any) -> Response:
    """The one place that renders a problem (see ``render_problem``); a 503 says when to retry."""
    status, body = render_problem(slug, detail, field=field, **extra)
    headers = {"Retry-After": str(RETRY_AFTER_S)} if status == 503 else None
    return Response(body, status_code=status, media_type=PROBLEM_MEDIA_TYPE, headers=headers)


# Discriminated unions put the tag in the error location (plant -> mode -> field); the user
# wrote plant.field, so tags are dropped from the reported path.
UNION_TAGS: frozenset[str] = frozenset(PLANT_KINDS)


def field_path(loc: tuple[Any, ...]) -> str:
    parts: list[str] = []
    for i, item in enumerate(loc):
        if i == 0 and item in ("body", "query", "path", "header"):
            continue
        if isinstance(item, str) and item in UNION_TAGS:
            continue
        if isinstance(item, str) and item.startswith("function-"):
            continue
        if isinstance(item, int):
            parts[-1:] = [f"{parts[-1]}[{item}]"] if parts else [f"[{item}]"]
        else:
            parts.append(str(item))
    return ".".join(parts) or "body"


MAX_REPORTED_ERRORS = 20


def validation_errors(exc: RequestValidationError) -> list[dict[str, Any]]:
    out = []
    for err in exc.errors()[:MAX_REPORTED_ERRORS]:
        rule = str(err.get("msg", "invalid"))
        field = field_path(tuple(err.get("loc", ())))
        if err.get("type") == "json_invalid":
            position = err.get("loc", ("body", "?"))[-1]
            rule = (
                f"the body is not valid JSON ({err.get('ctx', {}).get('error', 'parse error')} at character {position})"
            )
            field = "body"
        if rule.startswith("Value error, "):
            rule = rule[len("Value error, ") :]
        value = None if err.get("type") in ("missing", "json_invalid") else summarise(err.get("input"))
        out.append({"field": field, "value": value, "rule": rule})
    return out


def invalid_input(errors: list[dict[str, Any]], total: int | None = None) -> Response:
    first = errors[0]
    total = total or len(errors)
    detail = f"{first['field']}: {first['rule']}"
    if total > 1:
        detail += f" (and {total - 1} more)"
    return problem_response("invalid-input", detail, field=first["field"], errors=errors)


def domain_problem(exc: DomainError) -> Response:
    """The problem+json of a core error: its type is the error's own ``problem_type``."""
    slug = exc.problem_type
    if isinstance(exc, InvalidParameter):
        return invalid_input([{"field": exc.field, "value": summarise(exc.value), "rule": exc.rule}])
    if isinstance(exc, Infeasible | NotApplicable):
        return problem_response(slug, exc.reason, field=exc.field)
    if isinstance(exc, SolverFailed):
        extra: dict[str, Any] = {}
        if exc.report is not None:
            r = exc.report
            extra["solver"] = {"status": r.status, "iterations": r.iterations, "solve_time_s": r.solve_time_s}
        if hasattr(exc, "limit_s"):
            extra["limit_s"] = exc.limit_s
        return problem_response(slug, str(exc), **extra)
    response = problem_response(slug, str(exc))  # every 503 carries a Retry-After: the pool's own estimate here
    if isinstance(exc, PoolUnavailable):
        response.headers["Retry-After"] = str(exc.retry_after_s)
    return response


def install(app: FastAPI) -> None:
    """Register the handlers that turn every error into a problem, and the JSON body guard."""
    app.add_middleware(JSONBodyOnly)

    @app.exception_handler(RequestValidationError)
    async def _validation(_: Request, exc: RequestValidationError) -> Response:
        errors = validation_errors(exc)
        malformed = [e for e in errors if e["field"] == "body" and e["rule"].startswith("the body is not valid JSON")]
        if malformed:
            return problem_response("malformed-body", malformed[0]["rule"], field="body", errors=malformed[:1])
        return invalid_input(errors, total=len(exc.errors()))

    @app.exception_handler(DomainError)
    async def _domain(_: Request, exc: DomainError) -> Response:
        return domain_problem(exc)

    @app.exception_handler(ProblemError)
    async def _problem(_: Request, exc: ProblemError) -> Response:
        return problem_response(exc.slug, exc.detail, field=exc.field, **exc.extra)

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException) -> Response:
        response = _http_problem(exc)
        for name, value in (exc.headers or {}).items():  # e.g. a 405's Allow (RFC 9110 15.5.6)
            response.headers.setdefault(name, value)
        if exc.status_code == 405:
            allowed = allowed_methods(request.app, request.scope)
            if allowed:
                response.headers["Allow"] = ", ".join(allowed)
        return response

    def _http_problem(exc: StarletteHTTPException) -> Response:
        slug = {
            400: "malformed-body",
            404: "not-found",
            405: "method-not-allowed",
            406: "not-acceptable",
            413: "body-too-large",
            415: "unsupported-media-type",
        }.get(exc.status_code)
        if slug is None:
            text = safe_text(str(exc.detail))
            body = {"type": "about:blank", "title": text, "status": exc.status_code, "detail": text}
            return Response(dumps(body), status_code=exc.status_code, media_type=PROBLEM_MEDIA_TYPE)
        detail = str(exc.detail)
        if slug == "malformed-body" and detail == "There was an error parsing the body":  # FastAPI's words
            detail = "the body cannot be parsed as JSON: it is not UTF-8, or a number is beyond the parser's limits"
            return problem_response(
                slug, detail, field="body", errors=[{"field": "body", "value": None, "rule": detail}]
            )
        return problem_response(slug, detail)

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> Response:
        log.exception("unexpected error on %s %s", request.method, request.url.path)
        return problem_response("internal-error", "an unexpected error occurred; it has been logged")


METHOD_ORDER = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")


def allowed_methods(app: Any, scope: Scope) -> list[str]:
    """The methods the request's path accepts, over every route of the app that matches it (Starlette's 405
    names only the first route matching the path, and a StaticFiles mount its own). Empty if none says."""
    from fastapi import routing
    from starlette.routing import Match

    methods: set[str] = set()
    probe = {**scope, "type": "http", "method": ""}  # a method no route takes: the path matches PARTIAL at best
    iterate = getattr(routing, "iter_route_contexts", None)  # FastAPI >= 0.16x wraps included routers
    for context in iterate(app.routes) if iterate is not None else app.routes:
        if isinstance(getattr(context, "original_route", context), routing.Mount):
            continue  # a mount (the static files) answers its own 405, with its own Allow
        route_methods = getattr(context, "methods", None)
        if route_methods and context.matches(probe)[0] is not Match.NONE:
            methods.update(route_methods)
    return sorted(methods, key=lambda m: (METHOD_ORDER.index(m) if m in METHOD_ORDER else len(METHOD_ORDER), m))


def responses(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI declarations of the problems an operation can answer with."""
    out: dict[int | str, dict[str, Any]] = {}
    for status in statuses:
        slugs = [s for s, (code, _, _) in PROBLEM_TYPES.items() if code == status]
        out[status] = {
            "description": "; ".join(f"{PROBLEM_TYPES[s][1]} (/problems/{s})" for s in slugs),
            "content": {PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}},
        }
        if status == 503:
            out[status]["headers"] = {
                "Retry-After": {
                    "description": "Seconds to wait before retrying.",
                    "required": True,
                    "schema": {"type": "integer"},
                }
            }
    return out


def declared_statuses(route: Any) -> tuple[int, ...]:
    """Every problem status a route can answer with, from what it takes (the OpenAPI declares them all):

    - any route: 500 (internal-error);
    - a route with parameters or a body: 422 (invalid-input);
    - a route with a body: 400 (malformed-body), 413 (body-too-large), 415 (unsupported-media-type);
    - a route with a body that runs on the solver pool or the design threads (``app.deps.get_pool``,
      ``get_threads``): 503 (not-ready or busy, with Retry-After) and 504 (solve-timeout);
    - ``/problems/{slug}``: 404 (not-found).
    """
    from app.deps import get_pool, get_threads

    dependant = route.dependant
    statuses = {500}
    has_body = route.body_field is not None
    if has_body or dependant.query_params or dependant.path_params or dependant.header_params:
        statuses.add(422)
    if has_body:
        statuses.update({400, 413, 415})
        calls = set()
        stack = list(dependant.dependencies)
        while stack:
            dep = stack.pop()
            calls.add(dep.call)
            stack.extend(dep.dependencies)
        if get_pool in calls or get_threads in calls:
            statuses.update({503, 504})
    if route.endpoint is problem_type:
        statuses.add(404)
    return tuple(sorted(statuses))


class BodySizeLimit:
    """ASGI middleware: 413 problem for a body above ``max_bytes`` (declared or streamed).

    FastAPI's own ``max_body_size`` answers some of its 413s with a plain JSON body; this one
    always answers with a problem.
    """

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = dict(scope.get("headers", [])).get(b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.max_bytes:
            await self._reject(scope, receive, send)
            return
        received = 0
        started = False

        async def limited_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    raise _TooLarge()
            return message

        async def tracking_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, limited_receive, tracking_send)
        except _TooLarge:  # raised outside a route (a route turns it into its 413 problem)
            if not started:
                await self._reject(scope, receive, send)

    async def _reject(self, scope: Scope, receive: Receive, send: Send) -> None:
        response = problem_response(
            "body-too-large",
            f"the request body exceeds the limit of {self.max_bytes} bytes",
            limit_bytes=self.max_bytes,
        )
        await response(scope, receive, send)


def api_routes(app: Any) -> list[tuple[str, Any]]:
    """(path, route) of every FastAPI route of the app, in included routers too."""
    from fastapi import routing

    iterate = getattr(routing, "iter_route_contexts", None)  # FastAPI >= 0.16x wraps included routers
    contexts = list(iterate(app.routes)) if iterate is not None else list(app.routes)
    out = []
    for context in contexts:
        route = getattr(context, "original_route", context)
        path = getattr(context, "path_format", None) or getattr(route, "path_format", None)
        if isinstance(route, routing.APIRoute) and path is not None:
            out.append((path, route))
    return out


def is_json_media_type(content_type: str) -> bool:
    """``application/json`` or ``application/*+json``, with any parameters (charset, ...)."""
    media = content_type.split(";", 1)[0].strip().lower()
    kind, _, subtype = media.partition("/")
    return kind == "application" and (subtype == "json" or (subtype.endswith("+json") and len(subtype) > 5))


def extra_media_types(route: Any) -> frozenset[str]:
    """The non-JSON media types a route's OpenAPI ``requestBody`` declares (``openapi_extra``): the one way a
    route accepts another body (POST /v1/identify takes text/csv); none for every other route."""
    extra = getattr(route, "openapi_extra", None) or {}
    content = (extra.get("requestBody") or {}).get("content") or {}
    return frozenset(m.lower() for m in content if not is_json_media_type(m))


class JSONBodyOnly:
    """ASGI middleware: a 415 problem for a body that is not declared JSON, on a route that takes one.

    The routes that read a JSON body are found from the app's own routes (so a new route is covered
    without listing it). A body without a content-type is refused too (FastAPI would not parse it);
    a request without a body goes on (and meets the route's own "field required" 422). A route that
    declares another media type in its requestBody (``extra_media_types``) also takes that one.
    """

    def __init__(self, app: ASGIApp) -> None:
        self.app = app
        self._routes: list[tuple[Any, set[str], Any]] | None = None

    def _body_routes(self, scope: Scope) -> list[tuple[Any, set[str], Any]]:
        if self._routes is None:
            from starlette.routing import compile_path

            self._routes = [
                (compile_path(path)[0], set(route.methods or ()), route)
                for path, route in api_routes(scope["app"])
                if route.body_field is not None
            ]
        return self._routes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope.get("method") in ("GET", "HEAD", "OPTIONS", "DELETE"):
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers", []))
        length = headers.get(b"content-length")
        has_body = b"transfer-encoding" in headers or (length is not None and length.strip() not in (b"", b"0"))
        content_type = headers.get(b"content-type", b"").decode("latin-1")
        if has_body and not is_json_media_type(content_type):
            path, method = scope.get("path", ""), scope.get("method", "")
            route = next(
                (r for regex, methods, r in self._body_routes(scope) if regex.match(path) and method in methods), None
            )
            extra = extra_media_types(route) if route is not None else frozenset()
            if route is not None and content_type.split(";", 1)[0].strip().lower() not in extra:
                scope["route"] = route  # the access line and the metrics name the route, as for any answer
                sent = f"content-type {content_type!r}" if content_type else "no content-type"
                accepted = "application/json or application/*+json" + "".join(f" or {m}" for m in sorted(extra))
                rule = f"must be {accepted} (the body is JSON)" if not extra else f"must be {accepted}"
                response = problem_response(
                    "unsupported-media-type",
                    f"the body must be {accepted}; it was sent with {sent}"
                    if extra
                    else f"the body must be JSON (application/json or application/*+json); it was sent with {sent}",
                    field="content-type",
                    errors=[{"field": "content-type", "value": content_type or None, "rule": rule}],
                )
                await response(scope, receive, send)
                return
        await self.app(scope, receive, send)


class _TooLarge(StarletteHTTPException):
    """Raised from ``receive``: FastAPI re-raises HTTP exceptions met while reading a body."""

    def __init__(self) -> None:
        super().__init__(413, "the request body exceeds the configured size limit")


# Integers beyond 64 bits: orjson reads them as the nearest double, the standard parser as Python ints. A body
# with an integer token of 19 digits or more (``has_long_integer``) is read again by the standard parser when its
# validation fails, so that the 422 is the one ``json.loads`` gives (the field, the integer echoed as such).
_DIGIT_CLASSES = bytes(
    ord("d") if chr(c).isdigit() and c < 128 else ord(".") if c in b".+eE" else ord(" ") for c in range(256)
)
_LONG_INTEGER = b" " + b"d" * 19


def has_long_integer(body: bytes) -> bool:
    """Whether a JSON text may hold an integer of 19 digits or more (a run of 19 digits not after ``.``)."""
    classes = body.translate(_DIGIT_CLASSES)
    return classes.startswith(_LONG_INTEGER[1:]) or _LONG_INTEGER in classes


def parse_json(body: bytes, *, exact_integers: bool = False) -> Any:
    """A JSON body parsed by orjson (4x the standard parser on arrays of numbers, bench/http_io.py).

    What orjson refuses goes to the standard parser, so that the contract stays the one of ``json.loads``: the
    literals ``NaN``/``Infinity`` and numbers beyond double range (``1e999``) are read, then refused by the
    models as a 422 naming the field; lone surrogates (``"\\ud800"``) are read as before; invalid JSON raises
    the standard parser's ``JSONDecodeError`` (its message and position), and an integer beyond its 4300 digits
    its ``ValueError`` (FastAPI's 400). ``exact_integers``: the standard parser only (see ``JSONRoute``).
    orjson's error is itself a ``json.JSONDecodeError`` (https://github.com/ijl/orjson#deserialize)."""
    if exact_integers:
        return json.loads(body)
    try:
        return orjson.loads(body)
    except orjson.JSONDecodeError:
        return json.loads(body)


PARSE_IN_THREAD_BYTES = 256 * 1024  # above it a thread hop (~0.1 ms) is worth not blocking the event loop


class JSONRequest(Request):
    """Starlette's request whose ``json()`` is ``parse_json``: FastAPI reads every JSON body through it
    (``fastapi.routing.get_request_handler``)."""

    exact_integers = False

    async def json(self) -> Any:
        if not hasattr(self, "_json"):
            body = await self.body()
            if len(body) > PARSE_IN_THREAD_BYTES:  # megabytes of samples: parsed off the event loop
                self._json = await run_in_threadpool(parse_json, body, exact_integers=self.exact_integers)
            else:
                self._json = parse_json(body, exact_integers=self.exact_integers)
        return self._json


class JSONRoute(APIRoute):
    """An ``APIRoute`` whose handler gets a ``JSONRequest`` (FastAPI's documented way to change how a body is
    read: https://fastapi.tiangolo.com/how-to/custom-request-and-route/). Every router with a body uses it.

    A body refused by validation that holds a long integer token is validated again as the standard parser reads
    it (an exact Python int, not orjson's double): the 422 is then the one the service gave before orjson; the
    route's function has not run (FastAPI validates before calling it), so nothing runs twice."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()

        async def handle(request: Request) -> Response:
            fast = JSONRequest(request.scope, request.receive)
            try:
                return await handler(fast)
            except RequestValidationError:
                body = getattr(fast, "_body", None)
                if not hasattr(fast, "_json") or body is None or not has_long_integer(body):
                    raise
            exact = JSONRequest(request.scope, request.receive)
            exact._body = body
            exact.exact_integers = True
            return await handler(exact)

        return handle


router = APIRouter(tags=["problems"])


@router.get("/problems/{slug}", summary="What a problem type means")
async def problem_type(slug: str) -> dict[str, Any]:
    if slug not in PROBLEM_TYPES:
        raise ProblemError("not-found", f"no problem type {slug!r}; known: {', '.join(PROBLEM_TYPES)}")
    status, title, meaning = PROBLEM_TYPES[slug]
    return {"type": f"/problems/{slug}", "title": title, "status": status, "description": meaning}
