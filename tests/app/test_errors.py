"""Every bad input is a 422 (or 413) problem that names the field; nothing produces a 500."""

from __future__ import annotations

import json
import re

import pytest

from app.examples import CUSIMANO_8HZ, INCERTI_TABLE_III

MODE = {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": 0.05}


def assert_problem(response, status: int, field: str | None = None, slug: str = "invalid-input") -> dict:
    assert response.status_code == status, response.text
    assert response.headers["content-type"] == "application/problem+json"
    body = response.json()
    assert body["type"] == f"/problems/{slug}"
    assert body["status"] == status
    assert body["title"] and body["detail"]
    if field is not None:
        assert body["field"] == field, body
        assert body["errors"][0]["field"] == field
        assert body["errors"][0]["rule"]
    return body


@pytest.mark.parametrize(
    ("plant", "field"),
    [
        ({**CUSIMANO_8HZ, "motor_inertia_kgm2": -0.005}, "plant.motor_inertia_kgm2"),
        ({**CUSIMANO_8HZ, "load_inertia_kgm2": 0}, "plant.load_inertia_kgm2"),
        ({**MODE, "damping_ratio": 1.0}, "plant.damping_ratio"),
        ({**MODE, "damping_ratio": 1.5}, "plant.damping_ratio"),
        ({**MODE, "natural_frequency_hz": 0}, "plant.natural_frequency_hz"),
        ({**INCERTI_TABLE_III, "gear_ratio": -0.1}, "plant.gear_ratio"),
        ({"kind": "pendulum", "length_m": 1.0}, "plant"),
        ({"natural_frequency_hz": 5.0}, "plant"),  # no kind
        ({**MODE, "colour": "red"}, "plant.colour"),  # unknown field
        ({"kind": "mode"}, "plant.natural_frequency_hz"),  # missing field
        ({**MODE, "natural_frequency_hz": "fast"}, "plant.natural_frequency_hz"),
        # derived frequency sqrt(k/J_L)/2pi = 1.6e11 Hz is out of range
        # J_L at its minimum (1e-9 kg m^2): sqrt(k/J_L)/2pi = 5e9 Hz, above FREQUENCY_MAX_HZ
        ({**CUSIMANO_8HZ, "stiffness_nm_per_rad": 1e12, "load_inertia_kgm2": 1e-9}, "plant.stiffness_nm_per_rad"),
        # c = 3 on k = J_L = 1 gives zeta = 1.5: no vibration mode
        (
            {
                "kind": "two_inertia",
                "motor_inertia_kgm2": 1,
                "load_inertia_kgm2": 1,
                "stiffness_nm_per_rad": 1,
                "damping_nms_per_rad": 3,
            },
            "plant.stiffness_nm_per_rad",
        ),
        ({"kind": "transfer_function", "numerator": [1], "denominator": [1, -1, 4]}, "plant.denominator"),
        ({"kind": "transfer_function", "numerator": [1], "denominator": [1, 0]}, "plant.denominator"),
        ({"kind": "transfer_function", "numerator": [1, 2, 3], "denominator": [1, 2]}, "plant.numerator"),
        ({"kind": "transfer_function", "numerator": [1], "denominator": [1] * 30}, "plant.denominator"),
    ],
)
def test_invalid_plants(client, plant, field):
    assert_problem(client.post("/v1/plants/analyze", json={"plant": plant}), 422, field)


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_non_finite_numbers_are_refused(client, token):
    body = f'{{"plant": {{"kind": "mode", "natural_frequency_hz": {token}}}}}'
    response = client.post("/v1/plants/analyze", content=body, headers={"content-type": "application/json"})
    problem = assert_problem(response, 422, "plant.natural_frequency_hz")
    assert "finite" in problem["errors"][0]["rule"]


def test_non_finite_sample_is_refused(client):
    body = (
        '{"plant": {"kind": "mode", "natural_frequency_hz": 5}, '
        '"profile": {"time_s": [0, 1, 2], "velocity": [0, NaN, 1]}}'
    )
    response = client.post("/v1/simulate", content=body, headers={"content-type": "application/json"})
    assert_problem(response, 422, "profile.velocity[1]")


@pytest.mark.parametrize(
    ("profile", "field"),
    [
        ({"time_s": [0, 1, 1], "velocity": [0, 1, 1]}, "profile.time_s[2]"),
        ({"time_s": [0, 2, 1], "velocity": [0, 1, 1]}, "profile.time_s[2]"),
        ({"time_s": [0, 1, 2], "velocity": [0, 1]}, "profile.velocity"),
        ({"time_s": [0, 1, 2], "position": [0, 1, 2], "acceleration": [0, 1]}, "profile.acceleration"),
        ({"time_s": [0, 1]}, "profile"),
        ({"time_s": [0]}, "profile.time_s"),
        # each sample time is bounded (|t| <= 1e6, app/schemas/common.py): the error names the sample
        ({"time_s": [0, 1e12], "velocity": [0, 1]}, "profile.time_s[1]"),
        ({"time_s": [0, 1], "velocity": [0, 1e300]}, "profile.velocity[1]"),
        ({"time_s": [0, 1], "speed": [0, 1]}, "profile.speed"),
    ],
)
def test_invalid_profiles(client, profile, field):
    assert_problem(client.post("/v1/simulate", json={"plant": MODE, "profile": profile}), 422, field)


def test_more_samples_than_the_cap(client):
    n = 5001  # the test app's cap is 5000
    profile = {"time_s": list(range(n)), "velocity": [0.0] * n}
    problem = assert_problem(
        client.post("/v1/simulate", json={"plant": MODE, "profile": profile}), 422, "profile.time_s"
    )
    assert "5000" in problem["errors"][0]["rule"]


def test_held_quantity_must_be_given(client):
    request = {"plant": MODE, "profile": {"time_s": [0, 1], "velocity": [0, 1]}, "held_quantity": "jerk"}
    assert_problem(client.post("/v1/simulate", json=request), 422, "held_quantity")


def test_oversized_body_is_413(client):
    big = (
        b'{"plant": {"kind": "mode", "natural_frequency_hz": 5}, "profile": {"time_s": ['
        + b"0," * (1_100_000)
        + b"1]}}"
    )
    response = client.post("/v1/simulate", content=big, headers={"content-type": "application/json"})
    problem = assert_problem(response, 413, slug="body-too-large")
    assert problem["limit_bytes"] == 2 * 1024 * 1024


def test_oversized_streamed_body_is_413(client):
    def chunks():
        yield b'{"plant": {"kind": "mode", "natural_frequency_hz": 5}, "profile": {"time_s": ['
        for _ in range(300):
            yield b"0," * 5000
        yield b"1]}}"

    response = client.post("/v1/simulate", content=chunks(), headers={"content-type": "application/json"})
    assert_problem(response, 413, slug="body-too-large")


def test_malformed_json(client):
    # A body that is not JSON cannot be checked field by field: a 400 malformed-body (app/problem_handlers.py),
    # not a 422
    response = client.post("/v1/simulate", content=b'{"plant": ', headers={"content-type": "application/json"})
    assert_problem(response, 400, "body", slug="malformed-body")


def test_unknown_path_and_method_are_problems(client):
    assert_problem(client.get("/v1/nothing"), 404, slug="not-found")
    assert_problem(client.get("/v1/simulate"), 405, slug="method-not-allowed")


METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")


def declared_methods(app) -> dict[str, set[str]]:
    """Path template -> the methods its routes declare, over app.routes (included routers unwrapped); a mount of
    static files takes GET and HEAD (Starlette's StaticFiles)."""
    from fastapi.routing import iter_route_contexts
    from starlette.routing import Mount

    out: dict[str, set[str]] = {}
    for context in iter_route_contexts(app.routes):
        if isinstance(context.original_route, Mount):
            out.setdefault(context.path_format, set()).update({"GET", "HEAD"})
        else:
            out.setdefault(context.path_format, set()).update(context.methods)
    return out


def test_every_405_says_in_allow_which_methods_the_path_takes():
    """RFC 9110 15.5.6: a 405 MUST carry Allow, the methods the target resource supports; here every route of the
    app, every method it does not take. Two routes on one path (GET and POST declared apart) give both: the Allow
    of Starlette's 405 names only the first route that matches the path."""
    from fastapi.testclient import TestClient

    from app.main import create_app
    from tests.app.conftest import TEST_SETTINGS

    app = create_app(TEST_SETTINGS)
    app.add_api_route("/test/two-routes", lambda: {}, methods=["GET"])
    app.add_api_route("/test/two-routes", lambda: {}, methods=["POST"])
    routes = declared_methods(app)
    assert routes["/test/two-routes"] == {"GET", "POST"} and len(routes) > 15
    client = TestClient(app, raise_server_exceptions=False)  # no lifespan: a 405 needs no solver
    for template, allowed in routes.items():
        path = re.sub(r"{[^}]+}", "x", template)
        for method in sorted(set(METHODS) - allowed):
            response = client.request(method, path)
            assert response.status_code == 405, (method, path, response.status_code)
            assert {m.strip() for m in response.headers.get("allow", "").split(",")} == allowed, (method, path)
            if method != "HEAD":
                assert_problem(response, 405, slug="method-not-allowed")


def test_many_bad_samples_give_a_bounded_error_list(client):
    n = 4000
    body = json.dumps({"plant": MODE, "profile": {"time_s": ["x"] * n, "velocity": [0] * n}})
    problem = assert_problem(
        client.post("/v1/simulate", content=body, headers={"content-type": "application/json"}), 422
    )
    assert len(problem["errors"]) <= 20
    assert f"and {n - 1} more" in problem["detail"]


@pytest.mark.parametrize(
    "payload",
    [
        [],
        "plant",
        {"plant": None},
        {"plant": [1, 2]},
        {"plant": MODE, "profile": {"time_s": [[0], [1]], "velocity": [0, 1]}},
        {"plant": MODE, "profile": {"time_s": [0, 1e-300], "acceleration": [1e12, -1e12]}},
        {"plant": MODE, "profile": {"time_s": [0, 1e-9], "acceleration": [1e12, -1e12]}},
        {"plant": MODE, "profile": {"time_s": [1e7 - 1e-9, 1e7], "jerk": [1e12, -1e12]}},
        {"plant": MODE, "profile": {"time_s": [-1e7, 1e7], "acceleration": [1e12, -1e12]}},
        {"plant": {**MODE, "natural_frequency_hz": 1e5}, "profile": {"time_s": [0, 1e7], "jerk": [1e12, 1e12]}},
        {"plant": MODE, "profile": {"time_s": [0, 1], "velocity": [0, 1]}, "settling_tolerance": 0},
        {"plant": MODE, "profile": {"time_s": [0, 1], "velocity": [0, 1]}, "settling_window": 1e-300},
    ],
)
def test_odd_payloads_never_500(client, payload):
    response = client.post("/v1/simulate", json=payload)
    assert response.status_code in (200, 422), response.text
    if response.status_code == 200:
        text = response.text
        assert "NaN" not in text and "Infinity" not in text
