"""Bounded fuzzing of every operation against the app's own OpenAPI (schemathesis).

Schemathesis generates valid and invalid requests from /openapi.json (its examples, coverage and
fuzzing phases) and checks each answer: no 5xx, only the statuses and content types the operation
declares, a body that matches the declared schema (a problem for every error), and schema-invalid
input refused. The app runs its own lifespan (a one-worker solver pool) with small solve caps so that
random valid designs stay fast; the run is derandomised, so CI sees the same cases every time.
``bench/fuzz.py`` is the longer run whose figures are in the README.
"""

from __future__ import annotations

import json
import time

import pytest
import schemathesis
from fastapi import FastAPI
from hypothesis import HealthCheck, settings
from schemathesis.python import asgi
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    negative_data_rejection,
    response_headers_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from app.main import create_app
from app.settings import Settings

# Small caps: a random valid design takes at most about a second of solving.
FUZZ_SETTINGS = Settings(
    workers=1,
    max_samples=2000,
    max_body_bytes=256 * 1024,
    solve_time_limit_s=1.0,
    solve_max_iterations=300,
    solve_grace_s=2.0,
)
EXAMPLES_PER_OPERATION = 100
# A compare runs its solves one after the other on the one worker, each within its deadline (4 x 1 s + 2 s): more
# than schemathesis' 10 s default read timeout on a loaded machine.
CALL_TIMEOUT_S = 60.0
# not_a_server_error is replaced by the assertion in the test: a 504 solve-timeout (declared) is allowed.
CHECKS = [
    status_code_conformance,
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
    negative_data_rejection,
]


def fuzz_schema(app: FastAPI) -> schemathesis.schemas.BaseSchema:
    """The app's OpenAPI as a client reads it, bound to the app (called in-process over ASGI)."""
    schema = schemathesis.openapi.from_dict(json.loads(json.dumps(app.openapi())))
    schema.app = app  # what from_asgi does, without starting the app's lifespan when the module is collected
    return schema


def start_and_wait_ready(app: FastAPI, timeout_s: float = 120.0) -> None:
    """Start the app's lifespan (schemathesis keeps it running for its calls) and wait for the pool."""
    with asgi.get_client(app) as client:
        deadline = time.monotonic() + timeout_s
        while client.get("/readyz").status_code != 200:
            if time.monotonic() > deadline:
                raise AssertionError("the worker pool did not become ready")
            time.sleep(0.1)


APP = create_app(FUZZ_SETTINGS)
schema = fuzz_schema(APP)


@pytest.fixture
def running_app() -> None:
    # Schemathesis keeps the lifespan it starts until the process exits (its atexit hook stops the pool);
    # a per-test fixture, because schemathesis' generated items do not share module fixtures' teardown.
    start_and_wait_ready(APP)


@schema.parametrize()
@settings(
    max_examples=EXAMPLES_PER_OPERATION,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=list(HealthCheck),
)
def test_every_operation_survives_fuzzing(case: schemathesis.Case, running_app: None) -> None:
    response = case.call_and_validate(checks=CHECKS, timeout=CALL_TIMEOUT_S)
    # the only 5xx a valid request may meet is a solve that ran out of its (small) time cap
    assert response.status_code < 500 or response.json()["type"] == "/problems/solve-timeout", response.text
