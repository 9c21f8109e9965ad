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


def casadi_symbols(count: int) -> int:
    """Build ``count`` CasADi symbols (about 100 B each): past the worker's cap, C++ throws std::bad_alloc,
    which CasADi's Python binding raises as a RuntimeError, not a MemoryError."""
    import casadi

    return int(casadi.SX.sym("x", count).numel())
