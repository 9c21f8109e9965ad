"""Bad input never makes the service fall over: it is a 400, 413, 415 or 422 problem naming the field.

Expected values come from the brief of the input-hardening issue and from app/problems.py (with its handlers
and body middleware): a body that is not declared JSON is a 415 ``unsupported-media-type``; a body that is not
JSON a 400 ``malformed-body``; a value outside its schema range a 422 ``invalid-input`` naming the field; a
problem body never exceeds ``PROBLEM_MAX_BYTES`` (16 KiB).
"""

from __future__ import annotations

import json

import pytest
from fastapi.testclient import TestClient

from app.main import create_app
from app.problems import PROBLEM_MAX_BYTES, PROBLEM_MEDIA_TYPE, RETRY_AFTER_S, problem_response, render_problem
from app.settings import Settings
from tests.app.test_errors import assert_problem

MODE = {"kind": "mode", "natural_frequency_hz": 5.0}
# The papers' plants (app/examples.py); each test breaks one field at a time.
PLANTS = {
    "two_inertia": {
        "kind": "two_inertia",
        "motor_inertia_kgm2": 0.005,
        "load_inertia_kgm2": 0.005,
        "stiffness_nm_per_rad": 12.63,
    },
    "belt_platform": {
        "kind": "belt_platform",
        "platform_inertia_kgm2": 6.0,
        "branch_stiffness_n_per_m": 9e4,
        "branch_damping_ns_per_m": 150.0,
        "motor_pulley_radius_m": 0.06,
        "platform_pulley_radius_m": 0.18,
        "gear_ratio": 0.1,
    },
    "rigid_flexible": {
        "kind": "rigid_flexible",
        "drive_mass_kg": 2.0,
        "load_mass_kg": 3.0,
        "stiffness_n_per_m": 1.0,
        "damping_ns_per_m": 0.1,
        "drive_damping_ns_per_m": 30.0,
    },
    "mode": {"kind": "mode", "natural_frequency_hz": 40.0, "damping_ratio": 0.0},
}
# Fields a positive tiny value (the smallest double, 5e-324, or 1e-300) once passed and then divided by zero.
# Dampings may be 0 (so a tiny one is physical); every other parameter must be a physical amount.
MAY_BE_ZERO = {"damping_ns_per_m", "branch_damping_ns_per_m", "damping_nms_per_rad", "damping_ratio"}
TINY_FIELDS = [
    (kind, field) for kind, plant in PLANTS.items() for field in plant if field not in {"kind", *MAY_BE_ZERO}
]
TINY = (5e-324, 1e-300)


def post_operations(client: TestClient) -> list[str]:
    """Every POST operation of the OpenAPI that takes a body (a new route is covered without listing it here;
    the test-only routes of conftest.py take none)."""
    paths = client.get("/openapi.json").json()["paths"]
    return [path for path, ops in paths.items() if "requestBody" in ops.get("post", {})]


def test_every_post_refuses_a_body_that_is_not_json(client):
    paths = post_operations(client)
    assert len(paths) >= 9  # the nine POST endpoints of docs/api.md's table
    for path in paths:
        for content_type in ("text/plain", "application/x-www-form-urlencoded", "application/xml"):
            response = client.post(path, content=b'{"plant": {}}', headers={"content-type": content_type})
            assert_problem(response, 415, "content-type", slug="unsupported-media-type")


def test_a_body_without_content_type_is_refused(client):
    # The strict choice: FastAPI does not parse such a body as JSON, so it is a 415 rather than a 422.
    for path in post_operations(client):
        response = client.post(path, content=b'{"plant": {}}', headers={"content-type": ""})
        assert_problem(response, 415, "content-type", slug="unsupported-media-type")


@pytest.mark.parametrize(
    "content_type", ["application/json", "application/json; charset=utf-8", "application/vnd.x+json"]
)
def test_json_media_types_are_accepted(client, content_type):
    body = json.dumps({"plant": MODE}).encode()
    assert client.post("/v1/plants/analyze", content=body, headers={"content-type": content_type}).status_code == 200


@pytest.mark.parametrize("body", [b'{"plant": ', b"\xff\xfe{}", b"{'plant': 1}", b'{"plant": ' + b"1" * 5000 + b"}"])
def test_malformed_json_is_a_400(client, body):
    # invalid JSON, invalid UTF-8, Python's dict syntax, an integer beyond the parser's 4300 digits
    response = client.post("/v1/plants/analyze", content=body, headers={"content-type": "application/json"})
    assert_problem(response, 400, "body", slug="malformed-body")


@pytest.mark.parametrize(("kind", "field"), TINY_FIELDS)
@pytest.mark.parametrize("tiny", TINY)
def test_tiny_plant_parameters_are_422_naming_the_field(client, kind, field, tiny):
    plant = {**PLANTS[kind], field: tiny}
    response = client.post("/v1/plants/analyze", json={"plant": plant})
    assert_problem(response, 422, f"plant.{field}")


@pytest.mark.parametrize("limit", ["max_velocity", "max_acceleration", "max_jerk"])
@pytest.mark.parametrize("tiny", TINY)
def test_tiny_limits_are_422_naming_the_field(client, limit, tiny):
    body = {"plant": PLANTS["mode"], "displacement": 0.1, "limits": {limit: tiny}}
    for path in ("/v1/profiles/smoother", "/v1/profiles/time-optimal", "/v1/compare"):
        assert_problem(client.post(path, json=body), 422, f"limits.{limit}")


def test_tiny_transfer_function_coefficients_are_refused(client):
    # 5e-324 as the leading coefficient: the monic form overflows (models/plants.py refuses it)
    plant = {"kind": "transfer_function", "numerator": [1.0], "denominator": [5e-324, 1.0, 1.0]}
    assert_problem(client.post("/v1/plants/analyze", json={"plant": plant}), 422, "plant.denominator")


def test_an_integer_beyond_64_bits_is_a_422_naming_the_field(client):
    # 1e30 written as an integer: orjson cannot write it back, so the echoed value is text
    body = b'{"plant": {"kind": "mode", "natural_frequency_hz": 1000000000000000000000000000000}}'
    response = client.post("/v1/plants/analyze", content=body, headers={"content-type": "application/json"})
    problem = assert_problem(response, 422, "plant.natural_frequency_hz")
    assert problem["errors"][0]["value"] == "an integer of 100 bits"


@pytest.mark.parametrize(
    ("body", "field"),
    [
        (b'{"plant": {"kind": "\\ud800"}}', "plant"),
        (
            b'{"plant": {"kind": "transfer_function", "numerator": [1], "denominator": [1, 1, 1], '
            b'"command_input": "\\ud800"}}',
            "plant.command_input",
        ),
        (b'{"plant": {"kind": "mode", "natural_frequency_hz": "\\udfff"}}', "plant.natural_frequency_hz"),
    ],
)
def test_a_lone_surrogate_is_a_422_naming_the_field(client, body, field):
    response = client.post("/v1/plants/analyze", content=body, headers={"content-type": "application/json"})
    assert_problem(response, 422, field)


def test_a_boolean_is_not_a_number(client):
    # strict validation (app/schemas/common.py): JSON true is not the number 1
    plant = {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": False}
    assert_problem(client.post("/v1/plants/analyze", json={"plant": plant}), 422, "plant.damping_ratio")


def test_a_30_mb_bad_string_gives_a_problem_of_at_most_16_kib():
    # A separate app whose body limit admits 30 MB; its lifespan (the pool) is not started: validation
    # errors never reach it.
    app = create_app(Settings(max_body_bytes=40 * 1024 * 1024, workers=1))
    client = TestClient(app, raise_server_exceptions=False)
    big = "x" * 30_000_000
    for body in (
        {"plant": {"kind": big}},
        {"plant": {**MODE, big: 1}},
        {big: 1, "plant": MODE},
        {"plant": {"kind": "transfer_function", "numerator": [big], "denominator": [1, 2]}},
    ):
        response = client.post(
            "/v1/plants/analyze", content=json.dumps(body).encode(), headers={"content-type": "application/json"}
        )
        assert response.status_code == 422
        assert response.headers["content-type"] == PROBLEM_MEDIA_TYPE
        assert len(response.content) <= PROBLEM_MAX_BYTES


def test_a_problem_body_keeps_to_its_budget():
    # render_problem is the one renderer: many large errors are cut to fit, and the count of the dropped ones given
    errors = [{"field": f"f{i}", "value": {"k": ["v" * 150] * 8}, "rule": "r" * 900} for i in range(20)]
    status, body = render_problem("invalid-input", "d" * 10**6, field="\ud800" * 10, errors=errors, huge=10**40)
    problem = json.loads(body)
    assert status == 422 and len(body) <= PROBLEM_MAX_BYTES
    assert problem["errors_omitted"] == 20 - len(problem["errors"]) > 0
    assert problem["field"].startswith("\\ud800") and problem["huge"] == "an integer of 133 bits"


# Operations that run designs on the solver pool or the design threads (app/routers: they take PoolDep or
# ThreadsDep, and a body); /v1/simulate runs in the design threads.
POOL_OPERATIONS = {
    "/v1/simulate",
    "/v1/profiles/time-optimal",
    "/v1/profiles/pseudo-polynomial",
    "/v1/profiles/stap",
    "/v1/profiles/smoother",
    "/v1/profiles/input-shaped",
    "/v1/compare",
}


def test_every_status_is_declared_for_every_operation(client):
    # The statuses of app/problems.py's declared_statuses, each a Problem; 503 with its Retry-After header
    paths = client.get("/openapi.json").json()["paths"]
    for path, ops in paths.items():
        if path.startswith("/test/"):  # conftest.py's test-only routes
            continue
        for method, op in ops.items():
            declared = set(op["responses"])
            assert "500" in declared, (method, path)
            if "requestBody" in op:
                assert {"400", "413", "415", "422"} <= declared, (method, path)
            if path in POOL_OPERATIONS:
                assert {"503", "504"} <= declared, (method, path)
                assert op["responses"]["503"]["headers"]["Retry-After"]["required"] is True
            for status in declared - {"200"}:
                content = op["responses"][status]["content"]
                assert content == {PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}}
    assert "404" in paths["/problems/{slug}"]["get"]["responses"]
    for slug in ("malformed-body", "unsupported-media-type"):
        assert client.get(f"/problems/{slug}").status_code == 200


def test_every_503_says_when_to_retry():
    response = problem_response("not-ready", "the solver workers are starting")
    assert response.status_code == 503 and response.headers["Retry-After"] == str(RETRY_AFTER_S)
