"""Bounded work per request through HTTP (issue 23): the reproducers answer, closed-form designs run in the
process's design threads (runtime.threads) with their admission and deadlines, whose counts /readyz and /metrics
show. The lane itself is tested directly in tests/runtime/test_threads.py."""

from __future__ import annotations

import asyncio
import threading

import pytest
from fastapi.testclient import TestClient
from prometheus_client.parser import text_string_to_metric_families

from app.main import create_app
from app.settings import Settings
from tests.app.test_errors import assert_problem

PATH = "/v1/profiles/input-shaped"
# Issue 23's reproducer: a 330 Hz shaft (J_M 0.001, J_L 0.01, k 43000), 100 rad/s within 0.1 N m: an 11 s ramp
# whose torque check sampled 2000 points per period (7.3 million samples, 1.1 GB in the HTTP process).
REPRODUCER = {
    "plant": {
        "kind": "two_inertia",
        "load_inertia_kgm2": 0.01,
        "motor_inertia_kgm2": 0.001,
        "stiffness_nm_per_rad": 43000,
    },
    "target_velocity": 100,
    "limits": {"max_torque_nm": 0.1},
}


@pytest.mark.parametrize("stiffness", [43_000.0, 43_000_000.0])
def test_the_reproducer_and_a_1000_times_stiffer_shaft_meet_the_torque_limit(client, stiffness):
    body = {**REPRODUCER, "plant": {**REPRODUCER["plant"], "stiffness_nm_per_rad": stiffness}}
    response = client.post(PATH, json=body)
    assert response.status_code == 200, response.text
    answer = response.json()
    assert answer["limits_met"] and answer["metrics"]["peak_motor_torque_nm"] <= 0.1
    # the limit is the shaft's too: the acceleration limit is lowered below M / (J_M + J_L) = 9.0909
    assert answer["design"]["acceleration_limit"] < 0.1 / 0.011


def test_readyz_and_metrics_show_the_design_threads(client):
    threads = client.get("/readyz").json()["threads"]
    assert set(threads) == {"threads", "running", "queued", "held", "overrunning", "timeouts", "rejected"}
    assert threads["threads"] >= 1
    scraped = {
        sample.name: sample.value
        for family in text_string_to_metric_families(client.get("/metrics").text)
        for sample in family.samples
    }
    assert scraped["vibfree_threads_configured"] == threads["threads"]
    assert "vibfree_threads_rejected_total" in scraped and "vibfree_threads_timeouts_total" in scraped


def test_a_closed_form_design_is_refused_503_while_the_design_threads_are_full():
    # One design thread, no queue: while a job holds the thread, an input-shaped request is refused at once with
    # the pool's 503 busy and a Retry-After (it would have run in starlette's pool of 40 threads before); once
    # the thread is free the same request is answered.
    settings = Settings(workers=1, threads=1, max_thread_queued=0, max_samples=5000)
    with TestClient(create_app(settings), raise_server_exceptions=False) as client:
        lane = client.app.state.threads  # type: ignore[attr-defined]
        opened, holding = threading.Event(), threading.Event()

        def hold() -> None:
            holding.set()
            opened.wait(30.0)

        holder = threading.Thread(target=lambda: asyncio.run(lane.run(hold, deadline_s=30.0)))
        holder.start()
        try:
            assert holding.wait(30.0)
            response = client.post(PATH, json=REPRODUCER)
            assert "design thread" in assert_problem(response, 503, slug="busy")["detail"]
            assert int(response.headers["retry-after"]) >= 1
        finally:
            opened.set()
            holder.join(30.0)
        assert client.post(PATH, json=REPRODUCER).status_code == 200
        assert lane.stats()["rejected"] == 1
