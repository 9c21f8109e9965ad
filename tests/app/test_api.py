"""The HTTP endpoints: documented examples, the papers' numbers and agreement with the core."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.examples import CHATLATANAGULCHAI_EQ3, CUSIMANO_8HZ, INCERTI_TABLE_III
from models.commands import PiecewiseCommand
from models.plants import make_plant
from models.simulation import simulate
from tests.app.openapi_examples import post_examples


def _openapi(client):
    return client.get("/openapi.json").json()


def test_health_and_readiness(client):
    assert client.get("/healthz").json() == {"status": "ok"}
    ready = client.get("/readyz")
    assert ready.status_code == 200
    assert ready.json()["workers"] == 2


def test_docs_page_is_served(client):
    page = client.get("/docs")
    assert page.status_code == 200
    assert "swagger" in page.text.lower()


def test_every_post_operation_documents_an_example_and_its_problems(client):
    spec = _openapi(client)
    for path, item in spec["paths"].items():
        if path.startswith("/test/"):
            continue
        for method, operation in item.items():
            if method != "post":
                continue
            examples = operation["requestBody"]["content"]["application/json"].get("examples", {})
            assert examples, f"{path} has no worked example"
            for status in ("413", "422"):
                content = operation["responses"][status]["content"]
                assert content == {"application/problem+json": {"schema": {"$ref": "#/components/schemas/Problem"}}}
    assert "Problem" in spec["components"]["schemas"]
    assert "HTTPValidationError" not in spec["components"]["schemas"]


def test_every_documented_example_succeeds(client):
    spec = _openapi(client)
    count = 0
    for path, name, body in post_examples(spec):
        response = client.post(path, json=body)
        assert response.status_code == 200, (path, name, response.text)
        count += 1
    assert count >= 7


def test_analyze_reports_the_papers_modes(client):
    body = client.post("/v1/plants/analyze", json={"plant": INCERTI_TABLE_III}).json()
    (mode,) = body["modes"]
    assert mode["natural_frequency_rad_s"] == pytest.approx(31.1769, rel=2e-6)  # Incerti / PAPER-NOTES
    assert mode["damping_ratio"] == pytest.approx(0.025981, rel=2e-5)
    assert body["derived"]["transmission_ratio"] == pytest.approx(1 / 30)
    assert body["defines_energy"] is True
    body = client.post("/v1/plants/analyze", json={"plant": CHATLATANAGULCHAI_EQ3}).json()
    (mode,) = body["modes"]
    assert mode["natural_frequency_rad_s"] == pytest.approx(0.57703, abs=5e-6)  # eq. (3) as printed
    assert mode["damping_ratio"] == pytest.approx(0.057724, abs=5e-7)
    assert body["transfer_function"]["input"] == "velocity"
    assert body["transfer_function"]["denominator"] == pytest.approx([6.0, 90.5, 8.0, 30.0])


def test_simulate_returns_exactly_what_the_core_computes(client):
    t = np.linspace(0, 0.6, 301)
    acc = np.where(t < 0.3, 200 * np.sin(2 * np.pi * t / 0.3), 0.0)
    request = {"plant": CUSIMANO_8HZ, "profile": {"time_s": t.tolist(), "acceleration": acc.tolist()}}
    body = client.post("/v1/simulate", json=request).json()
    core = simulate(make_plant(**CUSIMANO_8HZ), PiecewiseCommand.from_samples(t, acc, 2))
    # orjson writes the shortest repr that round-trips, so the floats must be identical.
    assert body["load"]["position"] == core.load_position.tolist()
    assert body["load"]["motor_torque_nm"] == core.motor_torque_nm.tolist()
    assert body["profile"]["velocity"] == core.command.derivative(1).tolist()
    assert len(body["profile"]["time_s"]) == 301
    assert body["warnings"] == []
    assert body["metrics"]["peak_motor_torque_nm"] > 0


def test_cusimano_example_leaves_no_residual(client):
    body = client.post(
        "/v1/simulate",
        json={
            "plant": {"kind": "mode", "natural_frequency_hz": 40.0},
            "profile": {"time_s": [0, 0.025, 0.15, 0.175, 0.3], "acceleration": [0, 1000, 1000, 0, 0]},
        },
    ).json()
    metrics = body["metrics"]
    # Cusimano Sec. 3: t_j = 1/f_n = 0.025 s zeroes the residual at f_n = f_n,e (eq. 50).
    assert metrics["residual_velocity_amplitude"] < 1e-9 * 150
    assert metrics["settling_quantity"] == "velocity"
    assert metrics["settling_time_s"] == pytest.approx(0.175)
    assert body["profile"]["velocity"][-1] == pytest.approx(150.0)


def test_velocity_input_plant_has_no_deflection(client):
    body = client.post(
        "/v1/simulate",
        json={"plant": CHATLATANAGULCHAI_EQ3, "profile": {"time_s": [0, 1, 500], "velocity": [0, 1, 1]}},
    ).json()
    assert body["load"]["deflection"] is None
    assert body["metrics"]["final_energy_j"] is None
    # P(0) = 1/c0 (eq. 3); after 499 s the mode (sigma = 0.0333 1/s) has decayed by exp(-16.6).
    assert body["load"]["position"][-1] == pytest.approx(1 / 30, rel=1e-5)


def test_inconsistent_arrays_are_reported_as_a_warning(client):
    body = client.post(
        "/v1/simulate",
        json={
            "plant": {"kind": "mode", "natural_frequency_hz": 2.0},
            "profile": {"time_s": [0, 1, 2], "position": [0, 5, 5], "acceleration": [0, 0, 0]},
        },
    ).json()
    assert len(body["warnings"]) == 1
    assert "profile.position" in body["warnings"][0]
    assert body["profile"]["position"] == [0.0, 0.0, 0.0]  # the held acceleration wins


def test_problem_types_are_documented(client):
    body = client.get("/problems/invalid-input").json()
    assert body["status"] == 422
    missing = client.get("/problems/nope")
    assert missing.status_code == 404
    assert missing.headers["content-type"] == "application/problem+json"


def test_simulate_takes_the_settling_object_and_the_old_tolerance_as_an_alias(client):
    """A ramp to 1 on a 5 Hz, zeta 0.05 mode: the same settling from settling.position_tolerance and from the
    deprecated settling_tolerance; a tight vibration bound settles later (the envelope decays as e^(-sigma t))."""
    t = [i * 0.01 for i in range(201)]
    base = {
        "plant": {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": 0.05},
        "profile": {"time_s": t, "position": [min(x / 0.3, 1.0) for x in t]},
    }
    new = client.post("/v1/simulate", json={**base, "settling": {"position_tolerance": 0.01}}).json()
    old = client.post("/v1/simulate", json={**base, "settling_tolerance": 0.01}).json()
    assert new["metrics"]["settling_time_s"] == old["metrics"]["settling_time_s"]
    assert any("deprecated" in w for w in old["warnings"]) and not new["warnings"]
    tight = client.post(
        "/v1/simulate", json={**base, "settling": {"position_tolerance": 0.01, "vibration_tolerance": 1e-6}}
    ).json()["metrics"]
    assert tight["settling_vibration_window"] == 1e-6
    sigma = 0.05 * 2 * 3.141592653589793 * 5.0
    # One mode: the envelope after the ramp is A exp(-sigma (t - 0.3)); it reaches 1e-6 at 0.3 + ln(A / 1e-6) / sigma.
    amplitude = tight["residual_amplitude"]
    assert amplitude > 1e-3
    assert tight["settling_time_s"] == pytest.approx(0.3 + math.log(amplitude / 1e-6) / sigma, rel=1e-9)
    both = client.post("/v1/simulate", json={**base, "settling": {}, "settling_tolerance": 0.01})
    assert both.status_code == 422 and "settling_tolerance" in both.text
