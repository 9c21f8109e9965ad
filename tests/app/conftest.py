"""One running app (with its worker pool) for the API tests, plus test-only routes."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest
from fastapi import Request
from fastapi.testclient import TestClient

from app.main import create_app
from app.presenters import answer_body
from app.settings import Settings
from optim.solver import raise_for_status
from tests.app import slow_solves
from tests.runtime import pool_jobs

# The wall-clock deadline is a last resort (issue 23: every answer is decided by caps in units of work): the
# shared client's is 4 x 60 + 5 s, so that no verdict depends on the machine's load. The tests of the deadline
# itself (tests/app/test_pool.py, test_fuzz.py, tests/optim/test_compare_timeouts.py) set their own.
TEST_SETTINGS = Settings(
    workers=2, max_samples=5000, identify_max_rows=40_000, max_body_bytes=2 * 1024 * 1024, solve_time_limit_s=60.0
)


def _add_test_routes(app) -> None:
    async def slow(request: Request, seconds: float, deadline_s: float) -> dict:
        pid = await request.app.state.pool.run(slow_solves.sleep_for, seconds, deadline_s=deadline_s)
        return {"pid": pid}

    async def capped(request: Request, wall_time_s: float) -> dict:
        report = await request.app.state.pool.run(slow_solves.capped_ipopt, wall_time_s, deadline_s=30.0)
        raise_for_status(report)
        return {"status": report.status}

    async def allocate(request: Request, size: int) -> dict:
        return {"allocated": await request.app.state.pool.run(pool_jobs.allocate, size, deadline_s=30.0)}

    app.add_api_route("/test/slow", slow, methods=["POST"])
    app.add_api_route("/test/allocate", allocate, methods=["POST"])
    app.add_api_route("/test/capped", capped, methods=["POST"])


def wait_ready(client: TestClient, timeout_s: float = 90.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if client.get("/readyz").status_code == 200:
            return
        time.sleep(0.1)
    raise AssertionError("the worker pool did not become ready")


@pytest.fixture(scope="session")
def client() -> Iterator[TestClient]:
    app = create_app(TEST_SETTINGS)
    _add_test_routes(app)
    with TestClient(app, raise_server_exceptions=False) as test_client:
        wait_ready(test_client)
        yield test_client


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None):  # type: ignore[no-untyped-def]
    """tests/app/test_fuzz.py: one lifespan of its app (one solver pool) from its first fuzzed operation to its
    last. Schemathesis (4.x) ends every ASGI lifespan it started at each test's teardown, so each of the 15
    operations started and warmed a pool of its own; the lifespan is kept from one item using ``running_app`` to
    the next, and ended after the last."""
    uses = "running_app"
    if nextitem is None or uses not in getattr(item, "fixturenames", ()) or uses not in nextitem.fixturenames:
        yield
        return
    from schemathesis.python import asgi

    shutdown = asgi.shutdown_lifespans
    asgi.shutdown_lifespans = lambda: None
    try:
        yield
    finally:
        asgi.shutdown_lifespans = shutdown


def direct_body(family, schema, payload: dict, settings: Settings) -> dict:
    """A family endpoint's answer without HTTP: the same request through the pipeline in-process."""
    from app.responses import drop_duplicates
    from optim.synthesis import synthesize

    body = schema.model_validate(payload)
    problem = body.to_problem(settings)
    answer = answer_body(synthesize(family, problem, body.options(problem)))
    answer["warnings"] = [*body.deprecations, *answer["warnings"]]
    return drop_duplicates(answer)  # as the endpoint answers by default: no load.time_s
