"""GET /v1/shapers and POST /v1/profiles/input-shaped: every error is a problem naming the field or the reason."""

from __future__ import annotations

import pytest

from app.examples import CHATLATANAGULCHAI_EQ3
from tests.app.test_errors import assert_problem
from tests.app.test_shapers_api import FOUR_MODE_PLANT, PAPER, PATH

# ------------------------------------------------------------------------------------------
# Errors


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"shaper": "zvx"}, "shaper"),
        ({"acceleration_limit": -0.1}, "acceleration_limit"),
        ({"acceleration_limit": 0}, "acceleration_limit"),
        ({"baseline": "smooth"}, "baseline"),
        ({"target_velocity": 0.0}, "target_velocity"),
        ({"displacement": 3.0}, "target_velocity"),  # both given
        ({"cruise_velocity": 1.0}, "cruise_velocity"),  # only for rest-to-rest
        ({"vibration_tolerance": 0.9, "shaper": "ei"}, "vibration_tolerance"),
        ({"horizon_s": 10.0}, "horizon_s"),  # the command ends at 15.87 s
        ({"sample_period_s": 1e-5}, "sample_period_s"),  # 6e6 samples > the cap of 5000
        ({"baseline_steps": 4, "baseline": "multi_step"}, "baseline_steps"),
        ({"colour": "red"}, "colour"),
        ({"plant": {**CHATLATANAGULCHAI_EQ3, "drive_mass_kg": -2.0}}, "plant.drive_mass_kg"),
        ({"shaped_modes": "all", "plant": FOUR_MODE_PLANT}, "shaped_modes"),
    ],
)
def test_invalid_requests_are_problems_naming_the_field(client, change, field):
    assert_problem(client.post(PATH, json={**PAPER, **change}), 422, field)


def test_missing_move_and_missing_limit(client):
    request = {k: v for k, v in PAPER.items() if k != "target_velocity"}
    assert_problem(client.post(PATH, json=request), 422, "displacement")
    request = {k: v for k, v in PAPER.items() if k != "acceleration_limit"}
    # Neither name was sent: the error names the uniform field.
    body = assert_problem(client.post(PATH, json={**request, "baseline": "modified"}), 422, "limits.max_acceleration")
    assert "required" in body["errors"][0]["rule"]


def test_impossible_limits_are_infeasible_with_the_reason(client):
    # a = 0.05 < 0.0909: Delta = 9.918 s > t2 - t1 = 5.4535 s, the no-overlap condition fails.
    # The modified baseline, asked for explicitly, refuses with the reason.
    modified = {**PAPER, "acceleration_limit": 0.05, "baseline": "modified"}
    body = assert_problem(client.post(PATH, json=modified), 422, slug="infeasible")
    assert body["field"] == "acceleration_limit"
    assert "no-overlap" in body["detail"] and "0.0909" in body["detail"]
    # ... which multi_step with one step handles by lengthening the ramp (Delta = V/a = 20 s). The default
    # (auto) takes the earliest-ending valid baseline: three steps (26.84 s) beat that ramp (30.91 s), and
    # it says so.
    fixed = client.post(PATH, json={**PAPER, "acceleration_limit": 0.05, "baseline": "multi_step", "baseline_steps": 1})
    assert fixed.status_code == 200 and fixed.json()["ramp_time_s"] == pytest.approx(20.0, rel=1e-7)
    auto = client.post(PATH, json={**PAPER, "acceleration_limit": 0.05})
    assert auto.status_code == 200
    chosen = auto.json()["design"]["baseline"]
    assert chosen["kind"] == "multi_step" and len(chosen["step_times_s"]) == 3
    assert "ends before the single ramp" in chosen["choice"]
    ends = {a["steps"]: a["end_s"] for a in chosen["alternatives"]}
    assert auto.json()["design"]["duration_s"] == ends[3] == min(ends.values())
    assert ends[1] == pytest.approx(20.0 + 10.907045, abs=1e-6)  # Delta = V/a, then t_3 (5 decimals above)
    # An EI shaper beyond the damping where it exists, and a command too long to simulate.
    mode = {"kind": "mode", "natural_frequency_hz": 2.0, "damping_ratio": 0.5}
    request = {**PAPER, "plant": mode, "shaper": "3hump_ei", "horizon_s": None}
    body = assert_problem(client.post(PATH, json=request), 422, slug="infeasible")
    assert body["field"] == "vibration_tolerance"
    request = {**PAPER, "acceleration_limit": 1e-9, "horizon_s": None}
    body = assert_problem(client.post(PATH, json=request), 422, slug="infeasible")
    assert "beyond" in body["detail"]


@pytest.mark.parametrize(
    ("params", "field"),
    [({"damping_ratio": 1.5}, "damping_ratio"), ({"vibration_tolerance": 0}, "vibration_tolerance")],
)
def test_catalogue_query_errors(client, params, field):
    assert_problem(client.get("/v1/shapers", params=params), 422, field)
