"""``asyncio.run`` that works in any test: the browser tests' Playwright (sync API) keeps an event loop running
in the main thread for the rest of the session, where ``asyncio.run`` refuses to start."""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Coroutine
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")


def run(coroutine: Coroutine[Any, Any, T], runner: Callable[[Coroutine[Any, Any, T]], T] = asyncio.run) -> T:
    """Run ``coroutine`` to completion on a new event loop (``runner``'s: asyncio's, or e.g. ``uvloop.run``) in a
    thread of its own; return its result."""
    with ThreadPoolExecutor(max_workers=1) as thread:
        return thread.submit(runner, coroutine).result()
