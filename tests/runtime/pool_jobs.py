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


_KEPT: list[bytes] = []


def fragment_heap(mib: int) -> int:
    """Allocate ``mib`` MiB of small blocks and keep one in 200 (as a cache would): glibc cannot shrink its heap
    from the top past the kept ones, so the rest stays free heap in the process unless it is given back. The pid."""
    import os

    blocks = [bytes(2000) + bytes([i % 256]) for i in range(mib * 512)]
    _KEPT.extend(blocks[::200])
    return os.getpid()
