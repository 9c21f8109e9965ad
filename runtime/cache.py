"""Bounded caches of built solver problems: least recently used entries go first.

A worker builds a CasADi problem once per shape and keeps it (building costs 0.1-2 s); without a bound
a worker serving many plant kinds, orders and limit combinations grows for ever. Every module-level
cache of built problems is a ``LruCache`` registered here, so one setting sizes them all
(``VIBFREE_SOLVER_CACHE_SIZE``, applied in each new worker by ``optim.registry.warm_up_all``).
``ArrayCache`` bounds numpy tables by their bytes instead (the pseudo-polynomial quadrature rules:
one entry is up to 12.6 MB). A ``LruCache`` may also carry a budget in units of work (``weigh`` gives an
entry's estimated MiB from its key): entries are evicted before a build so that the kept ones and the new one
fit, since a count alone lets a worker keep 64 of the largest problems (the pseudo-polynomial's: ~90 MiB each).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterator
from typing import Generic, TypeVar

import numpy as np

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")

DEFAULT_SIZE = 64  # problems per cache: more than every warm-up builds (optim.registry.warm_up_all)
_registry: list[LruCache[object, object]] = []


class LruCache(Generic[K, V]):
    """A dict-like cache of at most ``size`` entries, evicting the least recently used."""

    def __init__(
        self,
        name: str,
        size: int | None = None,
        weigh: Callable[[K], float] | None = None,
        budget: float | None = None,
    ) -> None:
        self.name = name
        self.size = size or DEFAULT_SIZE
        self.weigh = weigh  # an entry's estimated cost from its key (MiB); with ``budget``, the sum is capped
        self.budget = budget
        self._entries: OrderedDict[K, V] = OrderedDict()
        self._weight = 0.0  # the weights of the held entries, kept as they come and go
        self._lock = threading.Lock()
        self.builds = 0
        self.evictions = 0
        _registry.append(self)  # type: ignore[arg-type]

    def get(self, key: K, build: Callable[[], V]) -> V:
        """The entry of ``key``, built by ``build()`` on a miss (and the oldest entries dropped)."""
        with self._lock:
            if key in self._entries:
                self._entries.move_to_end(key)
                return self._entries[key]
            if self.weigh is not None and self.budget is not None:  # make room before building, not after
                self._fit(self.budget - self.weigh(key))
        value = build()  # outside the lock: a build may take seconds
        with self._lock:
            if key not in self._entries:  # another thread may have built it meanwhile
                self._weight += self._weigh(key)
            self._entries[key] = value
            self._entries.move_to_end(key)
            self.builds += 1
            self._shrink()
        return value

    def resize(self, size: int) -> None:
        if size < 1:
            raise ValueError("a solver cache holds at least one problem")
        with self._lock:
            self.size = size
            self._shrink()

    def _weigh(self, key: K) -> float:
        return self.weigh(key) if self.weigh is not None else 0.0

    def _evict_oldest(self) -> None:
        key, _ = self._entries.popitem(last=False)
        self._weight = self._weight - self._weigh(key) if self._entries else 0.0  # no float drift left when empty
        self.evictions += 1

    def _shrink(self) -> None:
        while len(self._entries) > self.size:
            self._evict_oldest()
        if self.weigh is not None and self.budget is not None:
            self._fit(self.budget, keep=1)

    def _fit(self, room: float, keep: int = 0) -> None:
        """Evict the least recently used entries until their weights sum to at most ``room`` (or ``keep`` are left)."""
        while len(self._entries) > keep and self._weight > room:
            self._evict_oldest()

    @property
    def weight(self) -> float:
        """The estimated cost of the entries held (0 without ``weigh``)."""
        return self._weight

    def __contains__(self, key: object) -> bool:
        return key in self._entries

    def __len__(self) -> int:
        return len(self._entries)

    def __iter__(self) -> Iterator[K]:
        return iter(list(self._entries))

    def keys(self) -> list[K]:
        return list(self._entries)

    def clear(self) -> None:
        with self._lock:
            self._entries.clear()
            self._weight = 0.0


class ArrayCache(Generic[K, V]):
    """A cache of numpy tables bounded by their total bytes (``nbytes`` of every array in an entry)."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self._entries: OrderedDict[K, tuple[V, int]] = OrderedDict()
        self._lock = threading.Lock()
        self.bytes = 0

    def get(self, key: K, build: Callable[[], V]) -> V:
        with self._lock:
            if key in self._entries:
                self._entries.move_to_end(key)
                return self._entries[key][0]
        value = build()
        size = _nbytes(value)
        with self._lock:
            if key not in self._entries:
                self._entries[key] = (value, size)
                self.bytes += size
            while self.bytes > self.max_bytes and len(self._entries) > 1:
                _, (_, dropped) = self._entries.popitem(last=False)
                self.bytes -= dropped
        return value

    def __len__(self) -> int:
        return len(self._entries)

    def clear(self) -> None:
        with self._lock:
            self._entries.clear()
            self.bytes = 0


def _nbytes(value: object) -> int:
    if isinstance(value, np.ndarray):
        return int(value.nbytes)
    if isinstance(value, tuple | list):
        return sum(_nbytes(v) for v in value)
    return 0


def set_size(size: int) -> None:
    """Size every registered solver cache (and those created later) to ``size`` problems."""
    global DEFAULT_SIZE
    if size < 1:
        raise ValueError("a solver cache holds at least one problem")
    DEFAULT_SIZE = size
    for cache in _registry:
        cache.resize(size)


def caches() -> dict[str, int]:
    """Entries held by each registered cache (for tests and the memory bench)."""
    return {cache.name: len(cache) for cache in _registry}
