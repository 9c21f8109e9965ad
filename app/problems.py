"""RFC 9457 problem details: every error the service returns is ``application/problem+json``.

Each problem has its own ``type`` (a path under ``/problems/`` that the service documents), a
``title``, the HTTP ``status``, a ``detail`` sentence and, where one field is at fault, ``field``.
Invalid input lists every broken rule in ``errors`` with the field, the value and the rule.

Here the problem types, their rendering and their OpenAPI declarations; ``app.problem_handlers`` turns every
error into one, ``app.body_middleware`` answers a body too large or not JSON, ``app.json_bodies`` reads JSON.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from pydantic import BaseModel, ConfigDict, Field
from starlette.responses import Response

from app.encoding import dumps
from models.errors import DomainError, Infeasible, InvalidParameter, NotApplicable, PoolUnavailable, SolverFailed
from models.plants import PLANT_KINDS

PROBLEM_MEDIA_TYPE = "application/problem+json"
PROBLEM_TYPE_PATH = "/problems/{slug}"  # where a problem's type URI resolves (app.routers.problems)

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

    model_config = ConfigDict(extra="allow", title="Problem")
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
UNION_TAGS: frozenset[str] = frozenset((*PLANT_KINDS, "closed_loop"))


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


class InvalidRequestBody(Exception):
    """A request body that fails its schema where the service, not the route, validates it (a sweep's base
    request): pydantic's errors, their ``loc`` from the body's root. Answered as the 422 of a route's own."""

    def __init__(self, errors: Sequence[Mapping[str, Any]]) -> None:
        self.errors = list(errors)
        super().__init__(f"{len(self.errors)} validation errors")


def validation_errors(errors: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """pydantic's (or FastAPI's) errors as the problem's ``errors``: field, value and rule, at most 20."""
    out = []
    for err in errors[:MAX_REPORTED_ERRORS]:
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
    if route.path == PROBLEM_TYPE_PATH:
        statuses.add(404)
    return tuple(sorted(statuses))


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
