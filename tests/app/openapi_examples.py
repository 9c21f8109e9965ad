"""The worked examples the OpenAPI document gives for every POST operation (one walk for every test that posts them)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any


def post_examples(spec: dict[str, Any], paths: list[str] | None = None) -> Iterator[tuple[str, str, dict[str, Any]]]:
    """``(path, example name, request body)`` of every named example of every POST operation in ``spec`` (or of
    ``paths``), test-only routes (``/test/``) left out; an operation without examples yields nothing."""
    for path in spec["paths"] if paths is None else paths:
        operation = spec["paths"][path].get("post")
        if operation is None or path.startswith("/test/"):
            continue
        content = operation["requestBody"]["content"]["application/json"]
        for name, example in content.get("examples", {}).items():
            yield path, name, example["value"]


def first_post_examples(spec: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The first named example of every POST operation in ``spec``, by path (a warm-up calls each once)."""
    first: dict[str, dict[str, Any]] = {}
    for path, _, body in post_examples(spec):
        first.setdefault(path, body)
    return first
