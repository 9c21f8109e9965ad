"""The exception handlers that answer every error with an RFC 9457 problem, and the JSON body guard they install."""

from __future__ import annotations

import logging
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.responses import Response
from starlette.types import Scope

from app.body_middleware import JSONBodyOnly
from app.encoding import dumps
from app.problems import (
    PROBLEM_MEDIA_TYPE,
    InvalidRequestBody,
    ProblemError,
    domain_problem,
    invalid_input,
    problem_response,
    safe_text,
    validation_errors,
)
from models.errors import DomainError

log = logging.getLogger("app.problems")  # an unexpected error's log line names app.problems, as it always has


def install(app: FastAPI) -> None:
    """Register the handlers that turn every error into a problem, and the JSON body guard."""
    app.add_middleware(JSONBodyOnly)

    @app.exception_handler(RequestValidationError)
    async def _validation(_: Request, exc: RequestValidationError) -> Response:
        errors = validation_errors(exc.errors())
        malformed = [e for e in errors if e["field"] == "body" and e["rule"].startswith("the body is not valid JSON")]
        if malformed:
            return problem_response("malformed-body", malformed[0]["rule"], field="body", errors=malformed[:1])
        return invalid_input(errors, total=len(exc.errors()))

    @app.exception_handler(InvalidRequestBody)
    async def _invalid_body(_: Request, exc: InvalidRequestBody) -> Response:
        return invalid_input(validation_errors(exc.errors), total=len(exc.errors))

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
