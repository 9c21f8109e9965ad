"""JSON request bodies parsed by orjson (JSONRoute, JSONRequest), read again exactly where an integer is too long."""

from __future__ import annotations

import json
from collections.abc import Callable, Coroutine
from typing import Any

import orjson
from fastapi import Request
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from app.problems import InvalidRequestBody

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
    route's function has not run (FastAPI validates before calling it; a sweep's service validates its base request
    before it designs anything), so nothing runs twice."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()

        async def handle(request: Request) -> Response:
            fast = JSONRequest(request.scope, request.receive)
            try:
                return await handler(fast)
            except (RequestValidationError, InvalidRequestBody):  # a service's validation (a sweep's request)
                body = getattr(fast, "_body", None)
                if not hasattr(fast, "_json") or body is None or not has_long_integer(body):
                    raise
            exact = JSONRequest(request.scope, request.receive)
            exact._body = body
            exact.exact_integers = True
            return await handler(exact)

        return handle
