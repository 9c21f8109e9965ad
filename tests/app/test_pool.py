"""The solver worker pool: liveness while busy, capped solves, and killing a stuck worker.

These use test-only routes (tests/app/conftest.py) that run deliberately slow solves in the
app's own pool, through the same error handlers as the real endpoints.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

from tests.app.conftest import wait_ready
from tests.app.test_errors import assert_problem


def test_healthz_answers_while_every_worker_is_busy(client):
    with ThreadPoolExecutor(max_workers=2) as threads:
        busy = [threads.submit(client.post, "/test/slow", params={"seconds": 2.0, "deadline_s": 30}) for _ in range(2)]
        time.sleep(0.5)  # both workers are now sleeping in their 'solve'
        start = time.monotonic()
        health = client.get("/healthz")
        elapsed = time.monotonic() - start
        assert health.status_code == 200
        assert elapsed < 0.5, elapsed
        assert not any(f.done() for f in busy)
        pids = {f.result().json()["pid"] for f in busy}
    assert len(pids) == 2  # the two solves ran in two different worker processes


def test_ipopt_wall_time_cap_is_a_timeout_problem_without_a_result(client):
    response = client.post("/test/capped", params={"wall_time_s": 0.05})
    problem = assert_problem(response, 504, slug="solve-timeout")
    assert problem["solver"]["status"] == "Maximum_WallTime_Exceeded"
    assert problem["solver"]["iterations"] >= 1
    assert "profile" not in problem


def test_a_stuck_solve_is_killed_and_the_pool_recovers(client):
    start = time.monotonic()
    response = client.post("/test/slow", params={"seconds": 60.0, "deadline_s": 1.0})
    assert time.monotonic() - start < 10
    problem = assert_problem(response, 504, slug="solve-timeout")
    assert problem["limit_s"] == 1.0
    # Until the new workers are up the pool says so, with a problem and Retry-After.
    during = client.post("/test/slow", params={"seconds": 0.0, "deadline_s": 30})
    if during.status_code == 503:
        assert_problem(during, 503, slug="not-ready")
        assert during.headers["retry-after"]
    wait_ready(client)
    after = client.post("/test/slow", params={"seconds": 0.0, "deadline_s": 30})
    assert after.status_code == 200
