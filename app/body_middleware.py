"""ASGI middleware answering a request body's problems: too large (413, BodySizeLimit), not JSON (415, JSONBodyOnly)."""

from __future__ import annotations

from typing import Any

from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.problems import api_routes, problem_response


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
