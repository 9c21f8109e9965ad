"""Jobs for pool tests (importable by a spawned worker)."""

from __future__ import annotations


def big_answer(size: int) -> bytes:
    return b"x" * size
