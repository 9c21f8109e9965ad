"""Several HTTP processes (``vibfree serve --processes 2``): probes and metrics stay truthful whichever process
answers, and what dies is replaced. A real server in a subprocess (tests/app/server.py), one per module."""

from __future__ import annotations

import os
import signal
import time

import psutil
import pytest

from tests.app.server import get, readyz, scrape, serving

pytestmark = [
    pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="Linux process supervision"),
    pytest.mark.serial,  # kills the server's processes and reads their children: on the CPU first (tests/conftest.py)
]


@pytest.fixture(scope="module")
def port():
    with serving(2, env={"VIBFREE_WORKERS": "1"}) as port:
        yield port


def _requests_of(samples, route: str) -> float:
    return sum(
        v
        for (name, labels), v in samples.items()
        if name == "vibfree_http_requests_total" and dict(labels).get("route") == route
    )


def _wait(condition, timeout_s: float = 120.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.25)
    raise AssertionError("the condition did not hold in time")


def test_readyz_answers_for_both_processes_and_says_which_answered(port):
    status, body = readyz(port)
    assert status == 200
    pids = [row["pid"] for row in body["processes"]]
    assert len(pids) == 2 and body["pid"] in pids
    assert all(row["ready"] == 1 for row in body["processes"])  # VIBFREE_WORKERS=1: one warm worker each
    assert body["workers"] == 1


def test_requests_are_counted_once_whichever_process_answers(port):
    """K requests on fresh connections land on both processes (their pids are seen); the scrape, itself on
    either process, counts exactly K more: the counters are summed over the processes' files."""
    before = _requests_of(scrape(port), "/healthz")
    seen: set[int] = set()
    sent = 0
    while sent < 400 and (len(seen) < 2 or sent < 50):
        status, _ = get(port, "/healthz")
        assert status == 200
        sent += 1
        if sent % 5 == 0:  # which process answers, on a fresh connection too (not counted under /healthz)
            seen.add(readyz(port)[1]["pid"])
    assert len(seen) == 2, "the kernel gave every connection to one process: nothing was tested"
    for _ in range(4):  # a few scrapes, landing on either process, all see the same total
        assert _requests_of(scrape(port), "/healthz") - before == sent


def test_a_killed_solver_worker_of_one_process_is_replaced_and_counted(port):
    _, body = readyz(port)
    victim_parent = body["processes"][0]["pid"]
    (worker,) = psutil.Process(victim_parent).children()  # its one solver worker
    restarts_before = scrape(port)[("vibfree_pool_restarts_total", ())]
    os.kill(worker.pid, signal.SIGKILL)

    def replaced():
        # The children first: a readyz landing on the other process reads the victim's gauges from the shared
        # directory, stale until the victim's pool notices the death; once a new child exists, they are not.
        children = psutil.Process(victim_parent).children()
        if not children or children[0].pid == worker.pid:
            return None
        status, now = readyz(port)
        rows = {row["pid"]: row for row in now.get("processes") or []}
        return status == 200 and rows.get(victim_parent, {}).get("ready") == 1 and now

    now = _wait(replaced)
    assert {row["pid"] for row in now["processes"]} == {row["pid"] for row in body["processes"]}
    assert scrape(port)[("vibfree_pool_restarts_total", ())] == restarts_before + 1
    samples = scrape(port)
    assert samples[("vibfree_pool_workers", (("pid", str(victim_parent)), ("state", "ready")))] == 1


def test_a_killed_http_process_is_restarted_its_gauges_dropped_its_counts_kept(port):
    body = _wait(lambda: (lambda status, now: status == 200 and now)(*readyz(port)))
    before = _requests_of(scrape(port), "/healthz")
    victim = body["processes"][0]["pid"]
    os.kill(victim, signal.SIGKILL)  # no shutdown: its files stay until a scrape finds it dead

    def restarted():
        status, now = readyz(port)
        pids = {row["pid"] for row in now.get("processes") or now.get("pool", {}).get("processes") or []}
        return status == 200 and victim not in pids and len(pids) == 2 and now

    now = _wait(restarted)
    assert len(now["processes"]) == 2
    samples = scrape(port)
    assert not any(dict(labels).get("pid") == str(victim) for _, labels in samples)  # its live gauges are gone
    assert _requests_of(samples, "/healthz") >= before  # and its requests still counted (counters never fall)
