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
    assert lines[0] == "time_s,position,velocity,acceleration,jerk"  # the header first: no comment unless asked
    rows = np.loadtxt(lines[1:], delimiter=",")
    profile = {k: np.asarray(v) for k, v in json_body["profile"].items()}
    # The JSON samples every period and the end of the horizon; the CSV only the periods: the same numbers
    # there (both evaluate the law at the same instant; the law's own round-off is ~1e-12 of the move).
    # the default period: the 2.006 s horizon (the 1 s move and 5 periods of the mode) over about 2000
    # samples, rounded to 1, 2 or 5 times a power of ten: 2 ms, so 1004 rows
    period = 2e-3
    assert rows.shape[0] == 1004
    np.testing.assert_allclose(rows[:, 0], np.round(np.arange(rows.shape[0]) * period, 3), rtol=0, atol=0)
    at = np.searchsorted(profile["time_s"], rows[:, 0] - 1e-12)
    np.testing.assert_allclose(profile["time_s"][at], rows[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(rows[:, 1], profile["position"][at], rtol=0, atol=1e-9)
    np.testing.assert_allclose(rows[:, 4], profile["jerk"][at], rtol=1e-9, atol=1e-6)


# --- issue 11: the audit's reproducers answer a 200 within the limits (or a 422 with a reason) ------------

JERK_CASE = {
    "plant": {"kind": "mode", "natural_frequency_hz": 3.4136132292137797, "damping_ratio": 0.2840572223301995},
    "displacement": -717.9817512876891,
    "duration_s": 0.8859491534569945,
    "order": 3,
    "sample_period_s": 0.0011753363975126865,
    "limits": {"max_jerk": 118612.89875371839},
}
FALLBACK_CASE = {
    "plant": {
        "kind": "transfer_function",
        "numerator": [5329676.87849852, 21471366684.057102],
        "denominator": [1.0, 163.11501159112285, 689806.5368298043, 5329676.87849852, 21471366684.057102],
    },
    "displacement": 0.016550784134077873,
    "duration_s": 0.22808753015020575,
    "order": 3,
    "sample_period_s": 0.00020094309001385182,
    "limits": {"max_acceleration": 4.180686100801731, "max_jerk": 244.7660123724046},
}


def test_the_jerk_limit_holds_on_the_returned_samples(client):
    # Before: a 200 whose sampled jerk peaked at 118722 > 118613 (the solver's constraint grid let it through).
    # The pipeline's own check (metrics.peak_jerk of the sampled command, limit_violations) is the oracle.
    body = client.post(PATH, json=JERK_CASE).json()
    assert body["limit_violations"] == []
    assert body["metrics"]["peak_jerk"] <= JERK_CASE["limits"]["max_jerk"]
    assert body["profile"]["position"][-1] == pytest.approx(JERK_CASE["displacement"], rel=1e-12)


def test_a_failed_minimum_energy_search_falls_back_to_a_feasible_design(client):
    # Before: solver-failed ("no minimum-energy solve converged") although the classical 4-5-6-7 polynomial
    # meets both limits. Now the lowest-energy design within the limits met is returned, and said to be one.
    response = client.post(PATH, json=FALLBACK_CASE)
    assert response.status_code == 200, response.text
    body = response.json()
    design = body["design"]
    assert design["selection"] == "fallback" and "converged" in design["fallback_reason"]
    assert any(w.startswith("fallback:") for w in body["warnings"])
    assert body["limit_violations"] == []
    assert design["energy_ratio"] <= 1.0  # never worse than the classical polynomial it starts from
    assert body["metrics"]["residual_amplitude"] <= body["initial"]["metrics"]["residual_amplitude"] * (1 + 1e-6)


def test_the_duration_search_states_its_method_and_bracket(client):
    # minimize_duration's answer: the shortest feasible duration found, the longest infeasible one below it
    # (within the 0.1 % bisection stop), every solve counted in the solver summary.
    body = client.post(
        PATH,
        json={
            **TABLE_III_MOVE,
            "limits": {"max_velocity": 200.0, "max_acceleration": 700.0},
            "minimize_duration": True,
        },
    ).json()
    design = body["design"]
    bracket = design["duration_bracket"]
    assert bracket["shortest_feasible_s"] == design["duration_s"] == body["metrics"]["command_end_s"]
    assert design["duration_s"] * (1 - 1e-3) <= bracket["longest_infeasible_below_s"] < design["duration_s"]
    assert "kinematic floor" in design["duration_search_method"]
    assert body["solver"]["solves"] >= len(design["duration_search"]) > 1
    assert body["limit_violations"] == []
