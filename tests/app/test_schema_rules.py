"""The OpenAPI states the rules between fields that JSON Schema can state, exactly as validation checks them.

Issue 23: thousands of schema-valid fuzz requests were refused with a 422 for rules the schema did not say (a
move given twice, ``?columns=0``, a sweep axis with both ``values`` and ``start``). Each rule is now in the schema
(``oneOf``/``not``/``required``, a ``pattern``), and no stricter than validation: schemathesis' negative-data
check holds the app to refusing whatever the schema forbids. The expected verdict of every case below is
validation's own (the app's answer, or the parser's), and the schema must say the same.
"""

from __future__ import annotations

import re
from typing import Any

import jsonschema
import pytest
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st

from app.main import create_app
from app.responses import COLUMNS_PATTERNS, ProfileOutput, parse_fields
from app.schemas.family import SensitivityIn
from app.schemas.stap import StapOut
from models.errors import DomainError, PoolUnavailable
from optim import tables
from runtime.executor import InlineExecutor
from tests.app.conftest import TEST_SETTINGS

MODE = {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": 0.05}
LIMITS = {"max_velocity": 1.0, "max_acceleration": 10.0}
SHAPED = {"plant": MODE, "displacement": 1.0, "limits": LIMITS}
STAP = {"plant": MODE, "target_velocity": 1.0, "limits": {"max_acceleration": 10.0}}
TF = {"kind": "transfer_function", "numerator": [1.0], "denominator": [1.0, 0.2, 4.0]}
PROFILE = {"time_s": [0.0, 0.5, 1.0], "velocity": [0.0, 1.0, 0.0], "acceleration": [2.0, 0.0, -2.0]}
AXIS_RANGE = {"path": "plant.natural_frequency_hz", "start": 4.0, "stop": 6.0, "num": 3}


class NoSolver:
    """The pool's stand-in: a request that reaches a solver has passed every validation (a 503, not a 422)."""

    async def run(self, fn: Any, *args: Any, deadline_s: float) -> Any:
        raise PoolUnavailable("no solver in this test: the request passed validation")


@pytest.fixture(scope="module")
def app():
    application = create_app(TEST_SETTINGS)
    application.state.pool = NoSolver()  # no lifespan: no worker starts
    application.state.threads = InlineExecutor()  # closed forms run in the test (their physics checks are validation)
    return application


def schema_allows(openapi: dict[str, Any], path: str, body: Any, query: dict[str, str]) -> bool:
    """Whether the operation's OpenAPI (JSON Schema 2020-12) allows this body and query."""
    operation = openapi["paths"][path]["post"]
    body_schema = operation["requestBody"]["content"]["application/json"]["schema"]
    checks = [({**body_schema, "components": openapi["components"]}, body)]
    for parameter in operation.get("parameters", []):
        if parameter["in"] == "query" and parameter["name"] in query:
            checks.append((parameter["schema"], query[parameter["name"]]))
    return all(jsonschema.Draft202012Validator(schema).is_valid(value) for schema, value in checks)


# (path, body, query, validation accepts it): each case is one side of one rule; the rule is validation's (named)
CASES = [
    # ProfileRequest._resolved: exactly one of displacement and target_velocity
    ("/v1/profiles/input-shaped", SHAPED, {}, True),
    ("/v1/profiles/input-shaped", {**SHAPED, "target_velocity": 1.0}, {}, False),
    ("/v1/profiles/input-shaped", {"plant": MODE, "limits": LIMITS}, {}, False),
    ("/v1/profiles/input-shaped", {**SHAPED, "displacement": None, "target_velocity": 1.0}, {}, True),
    # optim.problem: |move| >= 1e-9
    ("/v1/profiles/input-shaped", {**SHAPED, "displacement": 1e-10}, {}, False),
    ("/v1/profiles/input-shaped", {**SHAPED, "displacement": -0.5}, {}, True),
    # InputShapedRequest._legacy_move: cruise_velocity is a rest-to-rest cruise
    ("/v1/profiles/input-shaped", {"plant": MODE, "target_velocity": 1.0, "cruise_velocity": 1.0}, {}, False),
    # the family's not_applicable: no jerk limit
    ("/v1/profiles/input-shaped", {**SHAPED, "limits": {**LIMITS, "max_jerk": 100.0}}, {}, False),
    # optim.families.input_shaped.shapers._check_name: the shaper names, in any case
    ("/v1/profiles/input-shaped", {**SHAPED, "shaper": " ZVDD"}, {}, True),
    ("/v1/profiles/input-shaped", {**SHAPED, "shaper": "zvx"}, {}, False),
    # ProfileRequest._resolved: settling_tolerance (deprecated) not beside settling
    ("/v1/profiles/input-shaped", {**SHAPED, "settling_tolerance": 0.01, "settling": {}}, {}, False),
    ("/v1/profiles/input-shaped", {**SHAPED, "settling_tolerance": 0.01}, {}, True),
    # responses.ProfileOutput: columns= (tables.check_columns) and fields= (parse_fields)
    ("/v1/profiles/input-shaped", SHAPED, {"columns": "0"}, False),
    ("/v1/profiles/input-shaped", SHAPED, {"columns": "position, load_position,"}, True),
    ("/v1/profiles/input-shaped", SHAPED, {"fields": "profile,metrics.settling_time_s"}, True),
    ("/v1/profiles/input-shaped", SHAPED, {"fields": " , "}, False),
    # SensitivityIn.count: an integral number is an integer (JSON Schema's integer)
    ("/v1/profiles/input-shaped", {**SHAPED, "sensitivity": {"count": 11.0}}, {}, True),
    # StapIn._legacy_move: both move fields (deprecated: target_velocity is the cruise speed)
    ("/v1/profiles/stap", {**STAP, "displacement": 2.0}, {}, True),
    # optim.families.stap.check_request and stap.ramp: a side band needs a whole k_j and t_a
    ("/v1/profiles/stap", {**STAP, "delta": 1}, {}, False),
    ("/v1/profiles/stap", {**STAP, "delta": 1, "jerk_periods": 1}, {}, False),
    ("/v1/profiles/stap", {**STAP, "delta": 1, "jerk_periods": 1, "acceleration_time_s": 1.0}, {}, True),
    ("/v1/profiles/stap", {**STAP, "jerk_periods": 2}, {}, True),
    ("/v1/profiles/stap", {**STAP, "jerk_periods": 0}, {}, False),
    ("/v1/profiles/stap", {**STAP, "jerk_periods": 0, "delta": 1, "acceleration_time_s": 1.0}, {}, True),
    # the STAP design: an acceleration limit (or torque, or a fixed t_a)
    ("/v1/profiles/stap", {**STAP, "limits": {}}, {}, False),
    ("/v1/profiles/stap", {**STAP, "limits": {}, "acceleration_time_s": 0.5}, {}, True),
    # the families' not_applicable: time-optimal needs a bound on the acceleration, pseudo-polynomial a displacement
    ("/v1/profiles/time-optimal", {"plant": MODE, "displacement": 1.0, "limits": {"max_velocity": 1.0}}, {}, False),
    ("/v1/profiles/time-optimal", SHAPED, {}, True),
    ("/v1/profiles/pseudo-polynomial", {"plant": MODE, "target_velocity": 1.0}, {}, False),
    ("/v1/profiles/pseudo-polynomial", {"plant": MODE, "displacement": 1.0}, {}, True),
    ("/v1/profiles/smoother", {"plant": MODE, "target_velocity": 1.0}, {}, False),
    ("/v1/profiles/smoother", {"plant": MODE, "displacement": 1.0}, {}, True),
    # optim.families.smoother.smoothers.design_chain: no filter needs a limit to design for
    ("/v1/profiles/smoother", {"plant": MODE, "displacement": 1.0, "filters": []}, {}, False),
    ("/v1/profiles/smoother", {"plant": MODE, "displacement": 1.0, "filters": [], "limits": LIMITS}, {}, True),
    # TimeOptimalIn.to_problem and optim.problem.Problem._check_states: a move in motion has a displacement; an
    # acceleration at either end needs a jerk limit
    ("/v1/profiles/time-optimal", {**SHAPED, "initial_state": {"velocity": 0.5}}, {}, True),
    ("/v1/profiles/time-optimal", {**STAP, "initial_state": {"velocity": 0.5}}, {}, False),
    ("/v1/profiles/time-optimal", {**STAP, "final_state": {"acceleration": 0}}, {}, False),
    ("/v1/profiles/time-optimal", {**SHAPED, "final_state": {"acceleration": 1.0}}, {}, False),
    ("/v1/profiles/time-optimal", {**SHAPED, "final_state": {"acceleration": 0.0}}, {}, True),
    (
        "/v1/profiles/time-optimal",
        {**SHAPED, "limits": {**LIMITS, "max_jerk": 100.0}, "initial_state": {"acceleration": -1.0}},
        {},
        True,
    ),
    # RobustnessIn._check: exactly one kind of robustness
    ("/v1/profiles/time-optimal", {**SHAPED, "robustness": {}}, {}, False),
    ("/v1/profiles/time-optimal", {**SHAPED, "robustness": {"derivative_order": 1.0}}, {}, True),
    # schemas.simulate.to_command: a quantity, the held one given, a cubic hold with its derivative
    ("/v1/simulate", {"plant": MODE, "profile": {"time_s": [0.0, 1.0]}}, {}, False),
    ("/v1/simulate", {"plant": MODE, "profile": PROFILE, "hold": "cubic"}, {}, True),
    ("/v1/simulate", {"plant": MODE, "profile": PROFILE, "held_quantity": "jerk"}, {}, False),
    ("/v1/simulate", {"plant": MODE, "profile": PROFILE, "hold": "cubic", "held_quantity": "acceleration"}, {}, False),
    ("/v1/simulate", {"plant": MODE, "profile": {**PROFILE, "velocity": None}, "hold": "cubic"}, {}, False),
    # SimulationOptions.settling_criteria: settling_tolerance (deprecated) not beside settling
    ("/v1/simulate", {"plant": MODE, "profile": PROFILE, "settling_tolerance": 0.01, "settling": {}}, {}, False),
    # models.plants.TransferFunctionPlant: a leading denominator coefficient, a numerator not all zeros
    ("/v1/plants/analyze", {"plant": TF}, {}, True),
    ("/v1/plants/analyze", {"plant": {**TF, "denominator": [0.0, 1.0, 4.0]}}, {}, False),
    ("/v1/plants/analyze", {"plant": {**TF, "numerator": [0.0, 0.0]}}, {}, False),
    ("/v1/plants/analyze", {"plant": {**TF, "denominator": [1.0, 0.2, 0.0]}}, {}, False),  # a pole at s = 0
    # AxisIn._one_kind: values, or start, stop and num; a log axis is positive
    ("/v1/sweeps", {"family": "stap", "request": STAP, "axes": [AXIS_RANGE]}, {}, True),
    ("/v1/sweeps", {"family": "stap", "request": STAP, "axes": [{**AXIS_RANGE, "values": [4.0, 5.0]}]}, {}, False),
    ("/v1/sweeps", {"family": "stap", "request": STAP, "axes": [{**AXIS_RANGE, "num": None}]}, {}, False),
    (
        "/v1/sweeps",
        {"family": "stap", "request": STAP, "axes": [{**AXIS_RANGE, "scale": "log", "start": 0}]},
        {},
        False,
    ),
    # app.services.sweeps.SweepPlan: the base request is the family's body, which has a plant tagged by its kind
    ("/v1/sweeps", {"family": "stap", "request": {**STAP, "plant": 1}, "axes": [AXIS_RANGE]}, {}, False),
    ("/v1/sweeps", {"family": "stap", "request": {**STAP, "plant": {"kind": "x"}}, "axes": [AXIS_RANGE]}, {}, False),
]


@pytest.mark.parametrize(("path", "body", "query", "accepted"), CASES)
def test_the_schema_allows_exactly_what_validation_accepts(app, path, body, query, accepted):
    response = TestClient(app, raise_server_exceptions=False).post(path, json=body, params=query)
    assert (response.status_code != 422) is accepted, response.text[:500]  # the expectation is validation's
    assert schema_allows(app.openapi(), path, body, query) is accepted


# Rules the schema leaves to the description (schemathesis' generator gives up on too many rules in one schema):
# validation refuses, the schema allows, and the operation's description states the rule.
DESCRIBED = [
    ("/v1/profiles/stap", {**STAP, "displacement": -2.0}, "displacement's sign"),
    ("/v1/profiles/stap", {**STAP, "optimization": {}}, "optimization applies to method optimized only"),
    ("/v1/profiles/input-shaped", {**SHAPED, "sensitivity": {"min_ratio": 1.5, "max_ratio": 0.5}}, "max_ratio"),
    ("/v1/sweeps", {"family": "stap", "request": STAP, "axes": [{**AXIS_RANGE, "stop": 3.0}]}, "stop greater"),
]


@pytest.mark.parametrize(("path", "body", "phrase"), DESCRIBED)
def test_a_rule_the_schema_does_not_state_is_in_the_operation_description(app, path, body, phrase):
    response = TestClient(app, raise_server_exceptions=False).post(path, json=body)
    assert response.status_code == 422, response.text[:300]  # validation's rule
    openapi = app.openapi()
    assert schema_allows(openapi, path, body, {})
    assert phrase in openapi["paths"][path]["post"]["description"]


def test_schemathesis_can_generate_requests_for_every_operation(app):
    """jsonschema_rs' canonical form, which schemathesis generates from, gives up ("UnsupportedSchema") on an
    operation whose rules between fields multiply to too many alternatives: then the fuzz tests stop at that
    operation. One valid and one invalid request for each operation that takes input."""
    import json

    import schemathesis
    from hypothesis import HealthCheck, Phase
    from hypothesis.errors import Unsatisfiable
    from schemathesis import GenerationMode

    schema = schemathesis.openapi.from_dict(json.loads(json.dumps(app.openapi())))
    drawn: list[Any] = []
    for result in schema.get_all_operations():
        operation = result.ok()
        if not operation.body and not any(True for _ in operation.iter_parameters()):
            continue
        for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE):
            before = len(drawn)

            @settings(
                max_examples=1,
                deadline=None,
                database=None,
                phases=[Phase.generate],
                suppress_health_check=list(HealthCheck),
            )
            @given(case=operation.as_strategy(generation_mode=mode))
            def draw(case: Any) -> None:
                drawn.append(case)

            try:
                draw()  # UnsupportedSchema fails the test
            except Unsatisfiable:  # no invalid value exists (a free-form path segment): nothing to generate
                assert mode is GenerationMode.NEGATIVE, operation.path
                continue
            assert len(drawn) > before, (operation.path, mode)


TOKENS = [*tables.COLUMNS, "all", "", " ", "\t", "\n", ",", ",", "0", "pos", "x"]


@settings(max_examples=400, derandomize=True, database=None, deadline=None)
@given(st.lists(st.sampled_from(TOKENS), max_size=8))
def test_the_columns_pattern_accepts_what_the_csv_parser_accepts(tokens):
    text = "".join(tokens)
    names = tuple(c.strip() for c in text.split(",") if c.strip())  # responses.ProfileOutput's split
    try:
        tables.check_columns(names)
        parsed = True
    except DomainError:
        parsed = False
    assert any(re.search(pattern, text) for pattern in COLUMNS_PATTERNS) is parsed, repr(text)


@settings(max_examples=400, derandomize=True, database=None, deadline=None)
@given(
    st.lists(
        st.sampled_from(["profile", "metrics.settling_time_s", "design", "nothing", "profile.", " ", ","]), max_size=6
    )
)
def test_the_fields_pattern_accepts_what_parse_fields_accepts(tokens):
    output = ProfileOutput(StapOut)
    text = "".join(tokens)
    try:
        parse_fields(text, output.allowed)
        parsed = True
    except DomainError:
        parsed = False
    assert (re.search(output.query_schemas()["fields"]["pattern"], text) is not None) is parsed, repr(text)


def test_an_integral_number_is_an_integer():
    """JSON Schema 2020-12 validation, 6.1.1: "integer" matches any number with a zero fractional part, so 11.0
    is the integer 11; the strict validation still refuses a fraction, a boolean and a string."""
    count = SensitivityIn.model_validate({"count": 11.0}).count
    assert count == 11 and type(count) is int
    for value in (11.5, True, "11"):
        with pytest.raises(ValueError):
            SensitivityIn.model_validate({"count": value})


def test_no_pydantic_constraint_name_leaks_into_the_schema(app):
    """ge, gt, le and lt are pydantic's names (a bound written after a validator in Annotated is emitted under
    them); JSON Schema knows only minimum, exclusiveMinimum, maximum and exclusiveMaximum, so a client (and
    schemathesis) would ignore the bound."""
    leaks = []
    stack = [("", app.openapi())]
    while stack:
        where, node = stack.pop()
        if isinstance(node, dict):
            if "type" in node and {"ge", "gt", "le", "lt"} & set(node):
                leaks.append(where)
            stack.extend((f"{where}/{k}", v) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((f"{where}/{i}", v) for i, v in enumerate(node))
    assert not leaks
