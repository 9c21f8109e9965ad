"""RFC 9457 problem details: every error the service returns is ``application/problem+json``.

Each problem has its own ``type`` (a path under ``/problems/`` that the service documents), a
``title``, the HTTP ``status``, a ``detail`` sentence and, where one field is at fault, ``field``.
Invalid input lists every broken rule in ``errors`` with the field, the value and the rule.
"""

from __future__ import annotations

import logging
from typing import Any

from fastapi import APIRouter, FastAPI, Request
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ConfigDict, Field
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.responses import Response
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from models.errors import DomainError, Infeasible, InvalidParameter, NotApplicable, PoolUnavailable, SolverFailed

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


class Problem(BaseModel):
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


def problem_response(slug: str, detail: str, *, field: str | None = None, **extra: Any) -> Response:
    from app.responses import dumps

    status, title, _ = PROBLEM_TYPES[slug]
    body: dict[str, Any] = {"type": f"/problems/{slug}", "title": title, "status": status, "detail": detail}
    if field is not None:
        body["field"] = field
    body.update(extra)
    return Response(dumps(body), status_code=status, media_type=PROBLEM_MEDIA_TYPE)


def summarise(value: Any) -> Any:
    """A value small enough to echo back: long lists become a short description."""
    if isinstance(value, (list, tuple)):
        return value if len(value) <= 8 else f"list of {len(value)} items"
    if isinstance(value, dict):
        return {k: summarise(v) for k, v in list(value.items())[:16]}
    if isinstance(value, str) and len(value) > 200:
        return value[:200] + "..."
    if isinstance(value, float) and value != value:
        return "NaN"
    if isinstance(value, float) and value in (float("inf"), float("-inf")):
        return "Infinity" if value > 0 else "-Infinity"
    return value


# Discriminated unions put the tag in the error location (plant -> mode -> field); the user
# wrote plant.field, so tags are dropped from the reported path.
UNION_TAGS: set[str] = set()


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


def _validation_errors(exc: RequestValidationError) -> list[dict[str, Any]]:
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
        value = None if err.get("type") == "missing" else summarise(err.get("input"))
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
    response = problem_response(slug, str(exc))
    if isinstance(exc, PoolUnavailable):
        response.headers["Retry-After"] = str(exc.retry_after_s)
    return response


def install(app: FastAPI) -> None:
    """Register the handlers that turn every error into a problem."""

    @app.exception_handler(RequestValidationError)
    async def _validation(_: Request, exc: RequestValidationError) -> Response:
        return invalid_input(_validation_errors(exc), total=len(exc.errors()))

    @app.exception_handler(DomainError)
    async def _domain(_: Request, exc: DomainError) -> Response:
        return domain_problem(exc)

    @app.exception_handler(ProblemError)
    async def _problem(_: Request, exc: ProblemError) -> Response:
        return problem_response(exc.slug, exc.detail, field=exc.field, **exc.extra)

    @app.exception_handler(StarletteHTTPException)
    async def _http(_: Request, exc: StarletteHTTPException) -> Response:
        slug = {404: "not-found", 405: "method-not-allowed", 406: "not-acceptable", 413: "body-too-large"}.get(
            exc.status_code
        )
        if slug is None:
            from app.responses import dumps

            body = {
                "type": "about:blank",
                "title": str(exc.detail),
                "status": exc.status_code,
                "detail": str(exc.detail),
            }
            return Response(dumps(body), status_code=exc.status_code, media_type=PROBLEM_MEDIA_TYPE)
        return problem_response(slug, str(exc.detail))

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> Response:
        log.exception("unexpected error on %s %s", request.method, request.url.path)
        return problem_response("internal-error", "an unexpected error occurred; it has been logged")


def responses(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI declarations of the problems an operation can answer with."""
    out: dict[int | str, dict[str, Any]] = {}
    for status in statuses:
        slugs = [s for s, (code, _, _) in PROBLEM_TYPES.items() if code == status]
        out[status] = {
            "description": "; ".join(f"{PROBLEM_TYPES[s][1]} (/problems/{s})" for s in slugs),
            "content": {PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}},
        }
    return out


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


class _TooLarge(StarletteHTTPException):
    """Raised from ``receive``: FastAPI re-raises HTTP exceptions met while reading a body."""

    def __init__(self) -> None:
        super().__init__(413, "the request body exceeds the configured size limit")


router = APIRouter(tags=["problems"])


@router.get("/problems/{slug}", summary="What a problem type means")
async def problem_type(slug: str) -> dict[str, Any]:
    if slug not in PROBLEM_TYPES:
        raise ProblemError("not-found", f"no problem type {slug!r}; known: {', '.join(PROBLEM_TYPES)}")
    status, title, meaning = PROBLEM_TYPES[slug]
    return {"type": f"/problems/{slug}", "title": title, "status": status, "description": meaning}
