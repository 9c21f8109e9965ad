"""Jobs for pool tests (importable by a spawned worker)."""

from __future__ import annotations


def big_answer(size: int) -> bytes:
    return b"x" * size


def allocate(size: int) -> int:
    """Allocate (and touch) ``size`` bytes; their count if it worked."""
    return len(bytearray(size))


def address_space_limit() -> int:
    import resource

    return resource.getrlimit(resource.RLIMIT_AS)[0]
