"""The command line's input and output: request files, answers written, and the service called (``--url``) or run
in-process, a refusal carrying its problem+json (vibfree.cli and its commands)."""

from __future__ import annotations

import sys
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO

import orjson

HTTP_TIMEOUT_S = 300.0


class Refused(Exception):
    """The service (or the in-process pipeline) refused the request: ``problem`` is its problem+json."""

    def __init__(self, problem: dict[str, Any]) -> None:
        self.problem = problem
        super().__init__(problem.get("detail", ""))


def read(path: str) -> bytes:
    data = sys.stdin.buffer.read() if path == "-" else Path(path).read_bytes()
    try:
        orjson.loads(data)
    except orjson.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    return data


def write(path: str | None, text: str) -> None:
    if path is None:
        return
    if path == "-":
        sys.stdout.write(text)
    else:
        Path(path).write_text(text)


def summary_stream(*outputs: str | None) -> TextIO:
    """stderr when the data goes to stdout, else stdout."""
    return sys.stderr if "-" in outputs else sys.stdout


def in_process(call: Any) -> Any:
    from vibfree.api import VibfreeError

    try:
        return call()
    except VibfreeError as exc:
        raise Refused(exc.problem) from None


def post(
    url: str, path: str, body: bytes, query: dict[str, Any] | None = None, content_type: str = "application/json"
) -> bytes:
    target = url.rstrip("/") + path + (f"?{urllib.parse.urlencode(query)}" if query else "")
    request = urllib.request.Request(target, data=body, method="POST", headers={"content-type": content_type})
    try:
        with urllib.request.urlopen(request, timeout=HTTP_TIMEOUT_S) as response:
            return bytes(response.read())
    except urllib.error.HTTPError as exc:
        raise refused(exc) from None
    except urllib.error.URLError as exc:
        raise OSError(f"cannot reach {url}: {exc.reason}") from None


def refused(exc: urllib.error.HTTPError) -> Refused:
    """The service's refusal: its problem+json (a Retry-After added to the detail)."""
    payload = exc.read()
    try:
        problem = orjson.loads(payload)
    except orjson.JSONDecodeError:
        problem = {"status": exc.code, "title": exc.reason, "detail": payload.decode(errors="replace")[:500]}
    if exc.code == 503 and exc.headers.get("Retry-After"):
        problem.setdefault("detail", "")
        problem["detail"] += f" (retry after {exc.headers['Retry-After']} s)"
    return Refused(problem)


def post_lines(url: str, path: str, body: bytes) -> Iterator[dict[str, Any]]:
    """POST and read the NDJSON answer line by line, as the service streams it."""
    target = url.rstrip("/") + path
    request = urllib.request.Request(target, data=body, method="POST", headers={"content-type": "application/json"})
    try:
        response = urllib.request.urlopen(request, timeout=HTTP_TIMEOUT_S)
    except urllib.error.HTTPError as exc:
        raise refused(exc) from None
    except urllib.error.URLError as exc:
        raise OSError(f"cannot reach {url}: {exc.reason}") from None
    with response:
        for raw in response:
            if raw.strip():
                yield orjson.loads(raw)
