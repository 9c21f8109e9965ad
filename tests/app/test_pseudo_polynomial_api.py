"""POST /v1/profiles/pseudo-polynomial through the HTTP layer and the worker pool."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.examples import INCERTI_TABLE_III
from tests.app.test_errors import assert_problem

PATH = "/v1/profiles/pseudo-polynomial"
TABLE_III_MOVE = {"plant": INCERTI_TABLE_III, "displacement": 30 * math.pi, "duration_s": 1.0}


def test_table_iii_acceptance(client):
    body = client.post(PATH, json=TABLE_III_MOVE).json()
    design = body["design"]
    # Issue acceptance: energy ratio below 1e-6, platform residual below 1e-6 rad, from ~3.5e-3 rad.
    assert design["energy_ratio"] < 1e-6
    assert design["residual_amplitude"] < 1e-6
    assert design["initial_residual_amplitude"] == pytest.approx(3.48e-3, rel=2e-3)
    assert design["solver"]["status"] == "Solve_Succeeded" and design["solver"]["iterations"] > 0
    assert design["energy_units"] == "J"
    assert body["metrics"]["residual_amplitude"] < 1e-6  # the returned samples, simulated
    assert body["initial"]["metrics"]["residual_amplitude"] == pytest.approx(3.48e-3, rel=2e-3)
    profile = body["profile"]
    assert set(profile) == {"time_s", "position", "velocity", "acceleration", "jerk"}
    assert profile["position"][-1] == pytest.approx(30 * math.pi, rel=1e-12)
    # Default sampling: about 2000 samples over the horizon 1 s + 5 periods (2.0077 s), rounded up to 2 ms.
    assert profile["time_s"][1] - profile["time_s"][0] == pytest.approx(2e-3)


def test_returned_samples_simulated_by_the_simulate_endpoint_agree(client):
    body = client.post(PATH, json=TABLE_III_MOVE).json()
    profile = body["profile"]
    # A user pastes the samples: velocity with its accelerations, cubic hold (the drive's cam table).
    again = client.post(
        "/v1/simulate",
        json={
            "plant": INCERTI_TABLE_III,
            "profile": {k: profile[k] for k in ("time_s", "position", "velocity", "acceleration")},
            "held_quantity": "velocity",
            "hold": "cubic",
        },
    ).json()
    assert again["metrics"]["residual_amplitude"] < 1e-6
    assert again["metrics"]["residual_amplitude"] == pytest.approx(
        body["metrics"]["residual_amplitude"], rel=1e-6, abs=1e-12
    )


def test_acceleration_limit_holds_on_the_returned_samples(client):
    body = client.post(PATH, json={**TABLE_III_MOVE, "limits": {"max_acceleration": 600.0}}).json()
    assert max(abs(a) for a in body["profile"]["acceleration"]) <= 600.0
    assert body["design"]["selection"] == "minimum_energy"
    assert any("zero-energy" in w for w in body["warnings"])


def test_impossible_limits_are_an_infeasible_problem(client):
    response = client.post(PATH, json={**TABLE_III_MOVE, "limits": {"max_velocity": 90.0}})
    problem = assert_problem(response, 422, slug="infeasible")
    assert problem["field"] == "limits.max_velocity"
    assert "94.2478" in problem["detail"]  # displacement / duration, the mean speed
    response = client.post(PATH, json={**TABLE_III_MOVE, "limits": {"max_acceleration": 450.0}})
    assert_problem(response, 422, slug="infeasible")


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"order": 9}, "order"),
        ({"initial_exponents": [3, 4]}, "initial_exponents"),
        ({"initial_exponents": [2.5, 4, 5]}, "initial_exponents"),
        ({"initial_exponents": [3, 3.01, 5]}, "initial_exponents"),  # closer than the 0.05 separation
        ({"displacement": 0}, "displacement"),
        ({"duration_s": -1}, "duration_s"),
        ({"sample_period_s": 1e-6}, "sample_period_s"),  # 2e6 samples: above the cap
        ({"horizon_s": 0.5}, "horizon_s"),
        ({"limits": {"max_torque_nm": 3.0}}, "limits.max_torque_nm"),  # belt_platform defines no torque
        ({"minimize_duration": True}, "minimize_duration"),  # no limit to minimise against
    ],
)
def test_invalid_requests(client, change, field):
    assert_problem(client.post(PATH, json={**TABLE_III_MOVE, **change}), 422, field)


def test_sensitivity_is_returned_when_asked(client):
    body = client.post(
        PATH, json={**TABLE_III_MOVE, "sensitivity": {"min_ratio": 0.8, "max_ratio": 1.2, "count": 41}}
    ).json()
    curve = body["sensitivity"]
    assert len(curve["frequency_ratio"]) == 41
    assert curve["quantity"] == "position"
    at_one = curve["residual_vibration"][20]
    assert at_one == pytest.approx(body["metrics"]["residual_amplitude"] / math.pi, rel=1e-6, abs=1e-12)
    assert np.max(curve["residual_vibration"]) > 10 * at_one  # it grows away from the design frequency


@pytest.mark.parametrize("how", [{"params": {"format": "csv"}}, {"headers": {"accept": "text/csv"}}])
def test_csv_export_for_a_cam_table(client, how):
    json_body = client.post(PATH, json=TABLE_III_MOVE).json()
    response = client.post(PATH, json=TABLE_III_MOVE, **how)
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/csv")
    lines = response.text.strip().splitlines()
    assert lines[0].startswith("#") and "units" in lines[0]
    assert lines[1] == "time_s,position,velocity,acceleration,jerk"
    rows = np.loadtxt(lines[2:], delimiter=",")
    assert rows.shape == (len(json_body["profile"]["time_s"]), 5)
    # Same numbers as the JSON profile, bit for bit (both are shortest round-trip reprs).
    np.testing.assert_array_equal(rows[:, 1], json_body["profile"]["position"])
    np.testing.assert_array_equal(rows[:, 4], json_body["profile"]["jerk"])
