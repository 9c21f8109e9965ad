"""The bounded thread lane (runtime.threads), driven directly: admission, the queue's and the work's deadlines.

The jobs block on events the test sets, so what runs when is decided by the test, not by timing; the deadlines
are short (0.2-0.5 s) only so that the tests end soon, and nothing asserts how long anything took.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable, Coroutine
from typing import Any

import pytest

from runtime.executor import PoolBusy
from runtime.threads import ThreadLane, WorkTimeout
from tests import aio


def run_async(main: Callable[[], Coroutine[Any, Any, None]]) -> None:
    aio.run(main())


class Gate:
    """A job that says it started, then waits until the test opens the gate; counts the jobs that ran."""

    def __init__(self) -> None:
        self.opened = threading.Event()
        self.lock = threading.Lock()
        self.started = 0
        self.most_at_once = 0
        self.now = 0

    def job(self, value: int) -> int:
        with self.lock:
            self.started += 1
            self.now += 1
            self.most_at_once = max(self.most_at_once, self.now)
        try:
            assert self.opened.wait(30.0), "the test never opened the gate"
            return value
        finally:
            with self.lock:
                self.now -= 1


async def until(condition: Callable[[], bool]) -> None:
    for _ in range(1500):  # 30 s at most: a condition that never holds fails the test
        if condition():
            return
        await asyncio.sleep(0.02)
    raise AssertionError("condition not reached")


def test_at_most_workers_run_and_at_most_max_queued_wait():
    # 2 threads, 3 waiting: 5 jobs are admitted, the 6th is refused at once with the pool's 503 busy, and no
    # more than 2 ever compute together; every admitted job then answers its own value.
    async def main() -> None:
        lane, gate = ThreadLane(2, 3), Gate()
        try:
            tasks = [asyncio.ensure_future(lane.run(gate.job, k, deadline_s=30.0)) for k in range(5)]
            await until(lambda: lane.stats()["running"] == 2 and lane.stats()["queued"] == 3)
            with pytest.raises(PoolBusy) as refused:
                await lane.run(gate.job, 99, deadline_s=30.0)
            assert refused.value.problem_type == "busy" and refused.value.retry_after_s >= 1
            assert lane.stats()["rejected"] == 1
            gate.opened.set()
            assert await asyncio.gather(*tasks) == [0, 1, 2, 3, 4]
            assert gate.most_at_once == 2 and gate.started == 5
            assert lane.stats() == {
                "threads": 2,
                "running": 0,
                "queued": 0,
                "held": 0,
                "overrunning": 0,
                "timeouts": 0,
                "rejected": 1,
            }
        finally:
            gate.opened.set()
            lane.close()

    run_async(main)


def test_a_job_that_waits_its_deadline_for_a_thread_is_refused_and_never_runs():
    async def main() -> None:
        lane, gate = ThreadLane(1, 4), Gate()
        try:
            first = asyncio.ensure_future(lane.run(gate.job, 1, deadline_s=30.0))
            await until(lambda: gate.started == 1)
            with pytest.raises(PoolBusy, match="no design thread became free"):
                await lane.run(gate.job, 2, deadline_s=0.2)
            assert lane.stats()["queued"] == 0 and lane.stats()["rejected"] == 1
            gate.opened.set()
            assert await first == 1
            await asyncio.sleep(0.1)
            assert gate.started == 1  # the refused job was dropped, not run later
        finally:
            gate.opened.set()
            lane.close()

    run_async(main)


def test_a_job_past_its_deadline_is_answered_504_and_keeps_its_thread_until_it_ends():
    # The answer is a WorkTimeout (504 solve-timeout) at the deadline; the thread cannot be stopped, so it keeps
    # its place (running, overrunning) and a new job waits for it: never more than `workers` threads compute.
    async def main() -> None:
        lane, gate = ThreadLane(1, 4), Gate()
        try:
            with pytest.raises(WorkTimeout) as timed_out:
                await lane.run(gate.job, 1, deadline_s=0.3)
            assert timed_out.value.problem_type == "solve-timeout"
            assert lane.stats()["running"] == 1 and lane.stats()["overrunning"] == 1
            assert lane.stats()["timeouts"] == 1
            second = asyncio.ensure_future(lane.run(gate.job, 2, deadline_s=30.0))
            await until(lambda: lane.stats()["queued"] == 1)
            assert gate.started == 1
            gate.opened.set()
            assert await second == 2
            assert gate.most_at_once == 1
            await until(lambda: lane.stats()["running"] == 0)
            assert lane.stats()["overrunning"] == 0
        finally:
            gate.opened.set()
            lane.close()

    run_async(main)


def test_a_caller_that_goes_away_drops_its_waiting_job():
    async def main() -> None:
        lane, gate = ThreadLane(1, 4), Gate()
        try:
            first = asyncio.ensure_future(lane.run(gate.job, 1, deadline_s=30.0))
            await until(lambda: gate.started == 1)
            waiting = asyncio.ensure_future(lane.run(gate.job, 2, deadline_s=30.0))
            await until(lambda: lane.stats()["queued"] == 1)
            waiting.cancel()
            await until(lambda: lane.stats()["queued"] == 0)
            gate.opened.set()
            assert await first == 1
            await asyncio.sleep(0.1)
            assert gate.started == 1
        finally:
            gate.opened.set()
            lane.close()

    run_async(main)


def test_errors_reach_the_caller_and_free_the_thread():
    def fails() -> None:
        raise ValueError("from the job")

    async def main() -> None:
        lane = ThreadLane(1, 0)
        try:
            with pytest.raises(ValueError, match="from the job"):
                await lane.run(fails, deadline_s=5.0)
            assert await lane.run(int, "7", deadline_s=5.0) == 7
            assert lane.stats()["running"] == 0
        finally:
            lane.close()

    run_async(main)


def test_a_reservation_is_all_or_nothing_and_its_jobs_keep_their_places():
    # Issue 23 (compare's closed forms): 2 threads + 1 waiting = 3 places. Two jobs run, so a request of 5 jobs,
    # which holds 2 places (as many as there are threads), is refused before any of its jobs exists (nothing is
    # queued, the refusal counts 2). Once one job ends it gets them; a plain job meanwhile finds no room (the
    # places are held, though no job of the request waits), and its 5 jobs run in its 2 places.
    async def main() -> None:
        lane, gate, first = ThreadLane(2, 1), Gate(), Gate()
        try:
            running = asyncio.ensure_future(lane.run(gate.job, 0, deadline_s=30.0))
            ending = asyncio.ensure_future(lane.run(first.job, -1, deadline_s=30.0))
            await until(lambda: lane.stats()["running"] == 2)
            with pytest.raises(PoolBusy, match="no room for the 2 designs"):
                async with lane.reserve(5):
                    raise AssertionError("a refused reservation must not run its block")
            assert lane.stats()["queued"] == 0 and lane.stats()["held"] == 0 and lane.stats()["rejected"] == 2
            first.opened.set()
            assert await ending == -1
            async with lane.reserve(5) as held:
                assert lane.stats()["held"] == 2
                with pytest.raises(PoolBusy):
                    await lane.run(gate.job, 99, deadline_s=30.0)
                jobs = [asyncio.ensure_future(held.run(gate.job, k, deadline_s=30.0)) for k in range(1, 6)]
                await until(lambda: lane.stats()["running"] == 2 and lane.stats()["queued"] == 1)
                assert lane.stats()["held"] == 0  # its 2 places: one job running, one waiting; 3 wait for them
                gate.opened.set()
                assert await asyncio.gather(*jobs) == [1, 2, 3, 4, 5]
                assert lane.stats()["held"] == 2  # each ended job gave its place back to the request
            assert await running == 0
            assert lane.stats()["held"] == 0 and lane.stats()["queued"] == 0 and gate.most_at_once == 2
        finally:
            gate.opened.set()
            first.opened.set()
            lane.close()

    run_async(main)
