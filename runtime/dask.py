"""Sweeps on a Dask cluster: ``DaskExecutor``, the ``Executor`` of an asynchronous ``dask.distributed`` client.

The sweep engine (``optim.sweeps``) runs its points on any ``Executor``; this one submits each as a task to the
cluster's scheduler. ``distributed`` is imported when a client connects, not with this module.
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib.util
import inspect
import logging
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any, TypeVar

from models.errors import PoolUnavailable
from runtime.executor import SolveTimeout

log = logging.getLogger(__name__)
T = TypeVar("T")


DASK_EXTRA = "pip install 'vibfree[dask]'"


def require_distributed() -> None:
    """Raise a ModuleNotFoundError that says what to install where Dask's ``distributed`` is missing (an optional
    extra: the service runs without it unless VIBFREE_DASK_SCHEDULER is set)."""
    if importlib.util.find_spec("distributed") is None:
        raise ModuleNotFoundError(f"design sweeps on a Dask cluster need Dask's distributed: {DASK_EXTRA}")


class DaskExecutor:
    """The ``Executor`` of a Dask cluster (``dask.distributed``, an asynchronous ``Client``): each job is one task.

    IPOPT is not thread-safe: run the workers with one thread each (``dask worker --nthreads 1``). A worker builds
    its family's solvers on its first point (``run_point``). A task that overruns ``deadline_s`` is reported as a
    timeout and cancelled (a running task finishes under the solver's own caps)."""

    def __init__(self, client: Any) -> None:
        self.client = client

    @classmethod
    @asynccontextmanager
    async def connect(cls, address: str, timeout_s: float = 10.0) -> AsyncIterator[DaskExecutor]:
        require_distributed()
        from distributed import Client

        try:
            client = await Client(address, asynchronous=True, timeout=timeout_s)  # type: ignore[no-untyped-call]
        except (OSError, TimeoutError) as exc:
            raise PoolUnavailable(f"cannot reach the Dask scheduler at {address}: {exc}") from None
        try:
            yield cls(client)
        finally:
            await client.close()

    async def capacity(self) -> int:
        """Threads across the cluster's workers (one point each)."""
        threads = self.client.nthreads()
        if inspect.isawaitable(threads):
            threads = await threads
        several = [w for w, n in threads.items() if n > 1]
        if several:
            log.warning("dask workers with several threads: IPOPT is not thread-safe", extra={"workers": several})
        return max(1, int(sum(threads.values())))

    async def run(self, fn: Callable[..., T], *args: Any, deadline_s: float) -> T:
        future = self.client.submit(fn, *args, pure=False)
        try:
            result: T = await asyncio.wait_for(future, deadline_s)
            return result
        except TimeoutError:
            raise SolveTimeout(deadline_s) from None
        finally:
            if not future.done():
                with contextlib.suppress(Exception):
                    await self.client.cancel([future])
