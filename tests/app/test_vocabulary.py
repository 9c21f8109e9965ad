"""One request vocabulary: every OpenAPI example gives identical numbers in its legacy and its new form,
the deprecated names are marked so in the schema, and each use of one adds a warning.

The legacy form of an example is written here independently of the service's alias table (the old
field names of each endpoint, before the pipeline issue), so a broken alias fails the comparison.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

from app.examples import CHATLATANAGULCHAI_EQ3
from app.main import create_app
from tests.app.conftest import TEST_SETTINGS
from tests.app.openapi_examples import post_examples

PROFILE_PATHS = (
    "/v1/profiles/pseudo-polynomial",
    "/v1/profiles/stap",
    "/v1/profiles/smoother",
    "/v1/profiles/input-shaped",
    "/v1/compare",
)


def legacy(path: str, body: dict[str, Any]) -> dict[str, Any]:
    """The example as the service's old vocabulary wrote it."""
    old = copy.deepcopy(body)
    limits = old.pop("limits", {})
    settling = old.pop("settling", None)
    if settling is not None:
        old["settling_tolerance"] = settling["position_tolerance"]
    if path.endswith("/stap"):
        if "max_acceleration" in limits:
            old["max_acceleration"] = limits.pop("max_acceleration")
        if "max_torque_nm" in limits:
            old["max_torque_nm"] = limits.pop("max_torque_nm")
        if "max_velocity" in limits and "displacement" in old:  # the cruise speed, signed
            old["target_velocity"] = math.copysign(limits.pop("max_velocity"), old["displacement"])
    elif path.endswith("/input-shaped"):
        if "max_acceleration" in limits:
            old["acceleration_limit"] = limits.pop("max_acceleration")
        if "max_velocity" in limits:
            old["cruise_velocity"] = limits.pop("max_velocity")
    if limits:
        old["limits"] = limits
    return old


EXAMPLES = list(post_examples(create_app(TEST_SETTINGS).openapi(), PROFILE_PATHS))


def with_settling(body: dict[str, Any]) -> dict[str, Any]:
    """Every example also exercises the settling alias (a tolerance other than the default)."""
    return {**body, "settling": {"position_tolerance": 2e-3}}


def numbers(body: Any) -> Any:
    """The answer without its warnings (the legacy form adds deprecation lines), the echoed request and
    the solvers' wall times."""
    if isinstance(body, dict):
        return {k: numbers(v) for k, v in body.items() if k not in ("warnings", "request", "solve_time_s")}
    if isinstance(body, list):
        return [numbers(v) for v in body]
    return body


def test_every_example_has_a_legacy_form_that_differs():
    changed = [name for path, name, body in EXAMPLES if legacy(path, with_settling(body)) != with_settling(body)]
    assert len(changed) == len(EXAMPLES)  # settling_tolerance at least
    assert any(legacy(p, b) != b for p, _, b in EXAMPLES if p.endswith("/stap"))
    assert any(legacy(p, b) != b for p, _, b in EXAMPLES if p.endswith("/input-shaped"))


@pytest.mark.parametrize(
    ("path", "name", "body"), EXAMPLES, ids=[f"{p.rsplit('/', 1)[-1]}:{n}" for p, n, _ in EXAMPLES]
)
def test_legacy_and_new_forms_give_identical_numbers(client, path, name, body):
    new_body = with_settling(body)
    new = client.post(path, json=new_body)
    old = client.post(path, json=legacy(path, new_body))
    assert new.status_code == 200, new.text
    assert old.status_code == 200, old.text
    new_answer, old_answer = new.json(), old.json()
    assert numbers(old_answer) == numbers(new_answer)  # exact: the same problem after the aliases
    if path != "/v1/compare":
        assert not any("deprecated" in w for w in new_answer["warnings"])
        assert sum("deprecated" in w for w in old_answer["warnings"]) >= 1
        assert [w for w in old_answer["warnings"] if "deprecated" not in w] == new_answer["warnings"]


def test_deprecated_fields_are_marked_in_the_schema(client):
    schemas = client.get("/openapi.json").json()["components"]["schemas"]
    expected = {
        "StapIn": {"max_acceleration", "max_torque_nm", "settling_tolerance"},
        "InputShapedRequest": {"acceleration_limit", "cruise_velocity", "settling_tolerance"},
        "PseudoPolynomialIn": {"settling_tolerance"},
        "SmootherRequest": {"settling_tolerance"},
        "CompareIn": {"settling_tolerance"},
    }
    for schema, fields in expected.items():
        properties = schemas[schema]["properties"]
        marked = {name for name, prop in properties.items() if prop.get("deprecated")}
        assert marked == fields, schema


def test_operation_ids_read_well(client):
    paths = client.get("/openapi.json").json()["paths"]
    ids = {op["operationId"] for item in paths.values() for op in item.values()}
    assert {"stap_profile", "pseudo_polynomial_profile", "smoother_profile", "input_shaped_profile", "compare"} <= ids
    assert not any("_v1_" in i or i.endswith("_post") for i in ids)


def test_a_legacy_field_that_contradicts_the_new_one_is_refused(client):
    body = {"plant": {"kind": "mode", "natural_frequency_hz": 5.0}, "target_velocity": 1.0}
    response = client.post(
        "/v1/profiles/stap", json={**body, "max_acceleration": 10.0, "limits": {"max_acceleration": 20.0}}
    )
    assert response.status_code == 422 and response.json()["field"] == "limits.max_acceleration"
    assert "deprecated max_acceleration" in response.json()["detail"]


def test_errors_name_the_field_the_caller_sent(client):
    # The same impossible limit sent under its new and its legacy name is reported under that name.
    plant = {"kind": "mode", "natural_frequency_hz": 5.0}
    new = client.post(
        "/v1/profiles/stap",
        json={"plant": plant, "target_velocity": 1.0, "limits": {"max_torque_nm": 1.0}},
    ).json()
    old = client.post("/v1/profiles/stap", json={"plant": plant, "target_velocity": 1.0, "max_torque_nm": 1.0}).json()
    assert new["field"] == "limits.max_torque_nm" and old["field"] == "max_torque_nm"


def test_a_core_error_is_named_in_the_callers_words(client):
    # The no-overlap condition fails at a = 0.05 (Chatlatanagulchai Sec. 4: Delta = 9.9 s > t2 - t1 = 5.45 s);
    # the shaping core names its acceleration limit, reported as the caller sent it.
    body = {"plant": CHATLATANAGULCHAI_EQ3, "shaper": "zvd", "target_velocity": 1.0, "baseline": "modified"}
    new = client.post("/v1/profiles/input-shaped", json={**body, "limits": {"max_acceleration": 0.05}}).json()
    old = client.post("/v1/profiles/input-shaped", json={**body, "acceleration_limit": 0.05}).json()
    assert new["type"] == old["type"] == "/problems/infeasible"
    assert (new["field"], old["field"]) == ("limits.max_acceleration", "acceleration_limit")
