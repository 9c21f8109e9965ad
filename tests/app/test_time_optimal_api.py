"""POST /v1/profiles/time-optimal through the HTTP layer and the worker pool, and its row in /v1/compare."""

from __future__ import annotations

import io

import numpy as np
import pytest

from app.examples.time_optimal import EXAMPLES
from app.schemas.time_optimal import TimeOptimalOut
from tests.app.test_errors import assert_problem

PATH = "/v1/profiles/time-optimal"
KNOWN = EXAMPLES["known_answer"]["value"]


def test_known_answer_over_http(client) -> None:
    response = client.post(PATH, json=KNOWN)
    assert response.status_code == 200, response.text
    body = TimeOptimalOut.model_validate(response.json())
    design = body.design
    assert design["duration_s"] == pytest.approx(0.2197077, rel=1e-4)  # the closed form
    assert design["lower_bound_s"] <= design["duration_s"]
    assert [a["kind"] for a in design["arcs"]] == ["bang"] * 4
    assert body.metrics.settling_time_s == pytest.approx(design["duration_s"], rel=1e-9)  # no residual to wait for
    # Newton on Singh and Vadali's structure, certified by its switching function: no LP, and the lower bound is
    # the duration itself (less the certificate's 1e-9)
    assert body.limits_met and body.solver is not None and body.solver.solves == 0
    assert design["lower_bound_s"] == pytest.approx(design["duration_s"], rel=2e-9)
    assert body.metrics.peak_velocity <= 5.0 and body.metrics.peak_acceleration <= 10.0 * (1 + 1e-9)


def test_csv_of_the_design(client) -> None:
    response = client.post(PATH, params={"format": "csv"}, json={**KNOWN, "sample_period_s": 1e-3})
    assert response.status_code == 200
    lines = [line for line in response.text.splitlines() if not line.startswith("#")]
    data = np.genfromtxt(io.StringIO("\n".join(lines)), delimiter=",", names=True)
    assert data["position"][-1] == pytest.approx(0.12, rel=1e-9)


@pytest.mark.parametrize("name", ["robust_band", "zvd_like", "jerk_limited", "two_inertia_torque", "in_motion"])
def test_examples(client, name: str) -> None:
    response = client.post(PATH, json=EXAMPLES[name]["value"])
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["limits_met"] and not body["limit_violations"]
    robustness = body["design"]["robustness"]
    if robustness is not None:
        assert robustness["covers_request"]
        assert robustness["worst_percentage_vibration"] <= robustness["max_percentage_vibration"] * (1 + 1e-9)


@pytest.mark.parametrize(
    ("patch", "field"),
    [
        ({"robustness": {"frequency_ratio_range": [0.9, 1.1], "derivative_order": 1}}, "robustness"),
        ({"robustness": {"frequency_ratio_range": [1.1, 0.9]}}, "robustness"),
        ({"robustness": {"frequency_ratio_range": [0.9, 1.1], "max_percentage_vibration": 0}}, None),
        ({"tradeoff": [0.95]}, "tradeoff"),
        ({"modes": [3]}, "modes[0]"),
        ({"max_duration_s": 0.1}, "max_duration_s"),
        ({"initial_state": {"velocity": 9.0}}, "initial_state.velocity"),  # above limits.max_velocity
        ({"final_state": {"acceleration": 1.0}}, "final_state.acceleration"),  # no max_jerk to ramp it
        ({"final_state": {"velocity": 1.0}, "displacement": None, "target_velocity": 1.0}, "final_state"),
        ({"initial_state": {"velocity": 1.0, "position": 0.0}}, "initial_state.position"),
    ],
)
def test_bad_input_names_the_field(client, patch: dict, field: str | None) -> None:
    body = assert_problem(client.post(PATH, json={**KNOWN, **patch}), 422)
    if field is not None:
        assert body["field"].startswith(field), body


def test_without_an_acceleration_bound_it_does_not_apply(client) -> None:
    body = assert_problem(
        client.post(PATH, json={**KNOWN, "limits": {"max_velocity": 5.0}}), 422, slug="not-applicable"
    )
    assert "max_acceleration" in body["detail"]


def test_an_unreachable_velocity_is_infeasible(client) -> None:
    request = {**KNOWN, "displacement": None, "target_velocity": 9.0}
    assert_problem(client.post(PATH, json=request), 422, slug="infeasible")


def test_an_impossible_band_is_proven_infeasible(client) -> None:
    request = {  # the case of tests/optim/test_time_optimal.py, where the relaxation is tight enough to prove it
        "plant": {"kind": "mode", "natural_frequency_hz": 5.0},
        "displacement": 0.3,
        "limits": {"max_velocity": 1.0, "max_acceleration": 10.0},
        "robustness": {"frequency_ratio_range": [0.5, 2.0], "max_percentage_vibration": 0.01},
        "max_duration_s": 0.6,
    }
    body = assert_problem(client.post(PATH, json=request), 422, slug="infeasible")
    assert "relaxation" in body["detail"]


def test_compare_puts_it_first(client) -> None:
    body = client.post("/v1/compare", json=KNOWN).json()
    first = body["rows"][0]
    assert first["family"] == "time_optimal"
    assert first["endpoint"] == PATH
    again = client.post(PATH, json=first["request"]).json()  # the row's request reproduces it
    assert again["metrics"]["settling_time_s"] == pytest.approx(first["settling_time_s"], rel=1e-9)


def test_a_band_bound_below_the_rounding_floor_is_a_422_naming_it(client):
    # The fuzz bench's 500 (V_max 5e-324 %: NaN in the LP's band rows); the floor is MIN_PERCENTAGE_VIBRATION.
    body = {
        "plant": {"kind": "mode", "natural_frequency_hz": 1.41498, "damping_ratio": 1e-288},
        "displacement": -0.28231,
        "limits": {"max_acceleration": 13923919666.894773},
        "robustness": {"frequency_range_hz": [11069.56, 15438.92], "max_percentage_vibration": 5e-324},
    }
    response = client.post("/v1/profiles/time-optimal", json=body)
    assert response.status_code == 422, response.text
    assert response.json()["field"] == "robustness.max_percentage_vibration"


def test_a_move_in_motion_starts_and_ends_in_it(client) -> None:
    """The profile starts at initial_state and ends at final_state; the residual is zero there (the family's
    independent checks are in tests/optim/test_time_optimal_motion.py)."""
    body = client.post(PATH, json=EXAMPLES["in_motion"]["value"]).json()
    profile, metrics = body["profile"], body["metrics"]
    assert profile["velocity"][0] == 0.2 and profile["velocity"][-1] == pytest.approx(0.1, abs=1e-12)
    assert profile["position"][-1] == pytest.approx(0.3 + 0.1 * (profile["time_s"][-1] - body["design"]["duration_s"]))
    assert metrics["residual_amplitude"] < 1e-12 and body["design"]["rigid_duration_s"] <= body["design"]["duration_s"]


def test_other_families_start_at_rest(client) -> None:
    body = assert_problem(
        client.post("/v1/profiles/input-shaped", json={**KNOWN, "initial_state": {"velocity": 1.0}}), 422
    )
    assert body["field"] == "initial_state"


def test_an_end_state_the_jerk_cannot_leave_within_the_velocity_limit_is_infeasible(client) -> None:
    """4.9 m/s at 9 m/s^2 reaches 4.9 + 9^2 / (2 x 100) = 5.3 m/s before a jerk of 100 m/s^3 brings the acceleration
    to 0: beyond max_velocity 5, whatever the command (optim.problem.Problem._check_overshoot)."""
    limits = {**KNOWN["limits"], "max_jerk": 100.0}
    body = {**KNOWN, "limits": limits, "initial_state": {"velocity": 4.9, "acceleration": 9.0}}
    problem = assert_problem(client.post(PATH, json=body), 422, slug="infeasible")
    assert problem["field"] == "initial_state" and "5.3" in problem["detail"]
