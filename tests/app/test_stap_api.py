"""POST /v1/profiles/stap through the HTTP layer (and the worker pool for method 'optimized')."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.examples import CUSIMANO_40HZ
from app.examples.stap import EXAMPLES
from app.schemas.stap import StapOut
from tests.app.test_errors import assert_problem

PATH = "/v1/profiles/stap"
SEC3 = {"plant": CUSIMANO_40HZ, "target_velocity": 150.0, "max_acceleration": 1000.0}


def two_inertia(load_inertia: float, frequency_hz: float = 8.0) -> dict:
    """The Table 2 motor (J_M = 0.005 kg m^2) with a load tuned to frequency_hz (k = J_L (2 pi f)^2)."""
    return {
        "kind": "two_inertia",
        "motor_inertia_kgm2": 0.005,
        "load_inertia_kgm2": load_inertia,
        "stiffness_nm_per_rad": load_inertia * (2 * math.pi * frequency_hz) ** 2,
    }


def simulate_samples(client, plant: dict, profile: dict) -> dict:
    """What a user does with the answer: paste the samples (acceleration, first-order hold) into /v1/simulate."""
    body = {"plant": plant, "profile": {"time_s": profile["time_s"], "acceleration": profile["acceleration"]}}
    response = client.post("/v1/simulate", json=body)
    assert response.status_code == 200, response.text
    return response.json()


@pytest.mark.parametrize(("k_j", "t_j", "t_a"), [(1, 0.025, 0.175), (2, 0.05, 0.2), (3, 0.075, 0.225)])
def test_section_3_acceptance(client, k_j, t_j, t_a):
    body = client.post(PATH, json={**SEC3, "jerk_periods": k_j}).json()
    design = body["design"]
    # Sec. 3: t_a,min = 150/1000 = 0.15 s (eq. 21), t_j = k_j/40 s (eq. 50), t_a = t_a,min + t_j (eq. 61).
    assert design["min_acceleration_time_s"] == pytest.approx(0.15, rel=1e-14)
    assert design["jerk_time_s"] == pytest.approx(t_j, rel=1e-14)
    assert design["acceleration_time_s"] == pytest.approx(t_a, rel=1e-14)
    assert design["constant_acceleration_time_s"] == pytest.approx(t_a - 2 * t_j, rel=1e-13)
    assert design["peak_acceleration"] == pytest.approx(1000.0, rel=1e-12)
    assert (design["shape"], design["k_j"], design["delta"]) == ("trapezoid", k_j, 0)
    assert design["residual_vibration"] < 1e-9
    profile = body["profile"]
    assert set(profile) == {"time_s", "position", "velocity", "acceleration", "jerk"}
    assert max(abs(a) for a in profile["acceleration"]) <= 1000.0 * (1 + 1e-12)
    for corner in (0.0, t_j, t_a - t_j, t_a):  # the corners are on the grid
        assert min(abs(t - corner) for t in profile["time_s"]) <= 1e-12
    # Acceptance: the returned samples, simulated independently of the design, leave < 1e-9 of v_max.
    again = simulate_samples(client, CUSIMANO_40HZ, profile)
    assert again["metrics"]["residual_velocity_amplitude"] <= 1e-9 * 150.0
    assert again["metrics"]["residual_velocity_amplitude"] == pytest.approx(
        body["metrics"]["residual_velocity_amplitude"], abs=1e-12
    )


def test_fig_17_side_band(client):
    body = client.post(PATH, json={**SEC3, "acceleration_time_s": 0.165, "jerk_periods": 0, "delta": 1}).json()
    design = body["design"]
    # t_j = dec(40 * 0.165)/40 = 0.015 s; the limit is reached (Appendix C, A21); zero residual, poor SC.
    assert design["jerk_time_s"] == pytest.approx(0.015, rel=1e-12)
    assert (design["k_j"], design["delta"], design["limit_reached"]) == (0, 1, True)
    assert design["load_acceleration_oscillation"] == pytest.approx(
        math.sin(0.6 * math.pi) / (0.6 * math.pi), rel=1e-12
    )
    assert design["band_worst_residual"] > 5 * 0.006  # k_j = 1 at t_a = 0.175 s: 0.0061 (tests/optim)
    assert [c["kind"] for c in design["candidates"]] == ["side_band"]
    assert any("Fig. 17" in w for w in body["warnings"])
    assert (
        simulate_samples(client, CUSIMANO_40HZ, body["profile"])["metrics"]["residual_velocity_amplitude"] <= 1e-9 * 150
    )


def test_eqs_45_46_and_the_zero_list(client):
    # Fig. 8: r = 6.7 (f = 33.5 Hz, t_a = 0.2 s), t^_j,max = 1/2: k_j,max = 3, delta_f = 0 (eqs. 45-46).
    request = {
        "plant": {"kind": "mode", "natural_frequency_hz": 33.5},
        "target_velocity": 150.0,
        "acceleration_time_s": 0.2,
        "jerk_periods": 1,
    }
    design = client.post(PATH, json=request).json()["design"]
    assert (design["paper_k_j_max"], design["paper_delta_f"], design["k_j_max"], design["delta_f"]) == (3, 0, 3, 0)
    assert len(design["candidates"]) == 6
    assert design["min_acceleration_time_s"] is None and design["acceleration_limit"] is None


def test_table_2_motor_with_torque_limit(client):
    plant = two_inertia(0.005)
    body = client.post(
        PATH, json={"plant": plant, "target_velocity": 150.0, "max_torque_nm": 10.0, "jerk_periods": 1}
    ).json()
    design, torque = body["design"], body["design"]["torque_limit"]
    # eq. 19: a_Max = 10/0.01 = 1000, t_a,min = 0.15 s; overshoot 0.0546 at 0.9 f_n,e; limit x 0.948.
    assert torque["nodal_acceleration_limit"] == pytest.approx(1000.0, rel=1e-12)
    assert torque["nodal_min_acceleration_time_s"] == pytest.approx(0.15, rel=1e-12)
    assert torque["torque_overshoot"] == pytest.approx(0.0546, abs=1e-4)
    assert torque["factor"] == pytest.approx(0.948, abs=5e-4)
    assert design["acceleration_limit"] == pytest.approx(948.19, abs=0.01)
    assert design["min_acceleration_time_s"] == pytest.approx(150 / 948.185, rel=1e-5)
    # The samples on the true plant at 0.9 f_n,e: the simulated motor torque stays within 10 N m and
    # comes within 0.1 % of it (the samples are 0.14 ms apart; the torque crest is 7 Hz wide).
    true = simulate_samples(client, two_inertia(0.005, 7.2), body["profile"])
    assert 9.99 <= true["metrics"]["peak_motor_torque_nm"] <= 10.0 * (1 + 1e-9)
    assert body["metrics"]["peak_motor_torque_nm"] <= 10.0
    # Without the frequency margin the limit is the nodal one and the true plant's torque exceeds 10 N m.
    bare = client.post(
        PATH,
        json={
            "plant": plant,
            "target_velocity": 150.0,
            "max_torque_nm": 10.0,
            "jerk_periods": 1,
            "frequency_uncertainty": 0,
        },
    ).json()
    assert bare["design"]["min_acceleration_time_s"] == pytest.approx(0.15, rel=1e-12)
    assert simulate_samples(client, two_inertia(0.005, 7.2), bare["profile"])["metrics"]["peak_motor_torque_nm"] > 10.5


def test_table_2_light_load_triangle(client):
    body = client.post(
        PATH, json={"plant": two_inertia(0.00125), "target_velocity": 150.0, "max_torque_nm": 10.0, "jerk_periods": 1}
    ).json()
    design = body["design"]
    # J_L = J_M/4: t_a,min = 150/1600 = 0.09375 s (eqs. 19, 21); t_j = 0.125 s > t_a,min: triangle,
    # 1200 rad/s^2 (eq. 31).
    assert design["torque_limit"]["nodal_min_acceleration_time_s"] == pytest.approx(0.09375, rel=1e-12)
    assert design["shape"] == "triangle" and design["acceleration_time_s"] == pytest.approx(0.25, rel=1e-12)
    assert design["peak_acceleration"] == pytest.approx(1200.0, rel=1e-12)
    assert max(abs(a) for a in body["profile"]["acceleration"]) == pytest.approx(1200.0, rel=1e-12)
    assert body["metrics"]["residual_velocity_amplitude"] < 1e-9 * 150


def test_sensitivity_uses_appendix_b_at_zero_damping(client):
    request = {
        **SEC3,
        "jerk_periods": 1,
        "sensitivity": {"min_ratio": 0.5, "max_ratio": 1.5, "count": 101, "damping_ratios": [0.0, 1e-12, 0.1]},
    }
    curve = client.post(PATH, json=request).json()["sensitivity"]
    assert curve["method"] == ["appendix_b", "free_state", "free_state"]
    grid = np.array(curve["residual_vibration_grid"])
    # Appendix B and the exact free state (zeta = 1e-12 changes it by ~1e-12) agree to 1e-9.
    np.testing.assert_allclose(grid[0], grid[1], rtol=0, atol=1e-9)
    assert curve["quantity"] == "velocity"
    assert grid[0][50] < 1e-12 and grid[2][50] > 1e-4  # zero at f_n,e undamped, not with zeta = 0.1
    # Percentage vibration: the reference is the unshaped ramp at 1000 rad/s^2 to 150 rad/s, two acceleration
    # steps whose undamped velocity envelope is 2 a / w at the true w = ratio x 2 pi 40.
    ratios = np.array(curve["frequency_ratio"])
    reference = 2 * 1000.0 / (ratios * 2 * np.pi * 40.0)
    np.testing.assert_allclose(curve["reference_amplitude"], reference, rtol=1e-12)
    percent = 100 * grid[0] * 150.0 / reference
    np.testing.assert_allclose(curve["percentage_vibration"], percent, rtol=1e-9, atol=1e-12)
    low, high = curve["band_5_percent"]
    centre = int(np.argmin(np.abs(ratios - 1.0)))
    first, last = centre, centre
    while first > 0 and percent[first - 1] <= 5.0:
        first -= 1
    while last < ratios.size - 1 and percent[last + 1] <= 5.0:
        last += 1
    # The contiguous band's ends lie between the last evaluated ratio inside and the first outside (0.01 apart).
    assert ratios[first] - 0.01 <= low <= ratios[first] and ratios[last] <= high <= ratios[last] + 0.01


def test_rest_to_rest_moves(client):
    body = client.post(PATH, json={**SEC3, "displacement": 30.0, "jerk_periods": 1}).json()
    design = body["design"]
    assert design["move"] == "rest_to_rest" and design["cruise_time_s"] == pytest.approx(0.025, rel=1e-12)
    assert design["total_time_s"] == pytest.approx(0.375, rel=1e-12)
    assert body["profile"]["position"][-1] == pytest.approx(30.0, rel=1e-13)
    assert body["profile"]["velocity"][-1] == 0.0
    # Acceptance: no residual at the nominal frequency, by simulation of the returned samples.
    again = simulate_samples(client, CUSIMANO_40HZ, body["profile"])
    assert again["metrics"]["residual_amplitude"] <= 1e-9 * 30.0
    short = client.post(PATH, json={**SEC3, "displacement": 10.0, "jerk_periods": 1}).json()
    assert short["design"]["velocity_lowered"] and short["design"]["cruise_velocity"] < 150.0
    assert any("lowered" in w for w in short["warnings"])
    assert simulate_samples(client, CUSIMANO_40HZ, short["profile"])["metrics"]["residual_amplitude"] <= 1e-9 * 10.0


def test_fastest_rest_to_rest_without_target_velocity(client):
    # D = v^2/a + v t_j with t_j = 1/40 s, a = 1000 (eq. 61 ramps, no cruise): v = 88.278 rad/s for 10 rad.
    body = client.post(PATH, json={"plant": CUSIMANO_40HZ, "displacement": 10.0, "max_acceleration": 1000.0}).json()
    design = body["design"]
    assert design["cruise_velocity"] == pytest.approx(500.0 * (-0.025 + math.sqrt(0.025**2 + 0.04)), rel=1e-12)
    assert design["cruise_time_s"] == 0.0 and design["requested_velocity"] is None
    assert any("fastest" in w for w in body["warnings"])
    StapOut.model_validate(body)


def test_negative_velocity_mirrors_the_profile(client):
    up = client.post(PATH, json={**SEC3, "jerk_periods": 1}).json()
    down = client.post(PATH, json={**SEC3, "target_velocity": -150.0, "jerk_periods": 1}).json()
    np.testing.assert_allclose(down["profile"]["acceleration"], -np.array(up["profile"]["acceleration"]))
    assert down["design"]["peak_acceleration"] == up["design"]["peak_acceleration"]


def test_optimized_on_a_damped_plant(client):
    plant = {"kind": "mode", "natural_frequency_hz": 40.0, "damping_ratio": 0.1}
    request = {**SEC3, "plant": plant, "acceleration_time_s": 0.2, "jerk_periods": 1}
    closed = client.post(PATH, json=request).json()
    optimised = client.post(PATH, json={**request, "method": "optimized"}).json()
    # Acceptance (tests/optim has the figures): at the same t_a the optimised design leaves less residual.
    assert optimised["design"]["acceleration_time_s"] == closed["design"]["acceleration_time_s"]
    assert optimised["design"]["residual_vibration"] < 0.9 * closed["design"]["residual_vibration"]
    assert any("zeta" in w for w in closed["warnings"])
    opt = optimised["design"]["optimization"]
    assert opt["selection"] == "optimized" and opt["solver"]["status"] in (
        "Solve_Succeeded",
        "Solved_To_Acceptable_Level",
    )
    assert opt["closed_form"]["nominal_residual"] == pytest.approx(closed["design"]["residual_vibration"], rel=1e-9)
    assert max(abs(a) for a in optimised["profile"]["acceleration"]) <= 1000.0 * (1 + 1e-12)
    assert not [w for w in optimised["warnings"] if "deprecated" not in w]  # SEC3 uses the legacy max_acceleration


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_every_documented_example_works(client, name):
    response = client.post(PATH, json=EXAMPLES[name]["value"])
    assert response.status_code == 200, response.text
    body = response.json()
    for key in ("acceleration_time_s", "jerk_time_s", "peak_acceleration", "residual_vibration"):
        assert math.isfinite(body["design"][key])
    assert all(math.isfinite(x) for x in body["profile"]["position"])
    assert all(math.isfinite(x) for x in body["load"]["velocity"])
    StapOut.model_validate(body)  # the documented response model describes the body (extra fields forbidden)
    assert body["design"]["auto_rule"].startswith("auto follows the Fig. 25 flowchart")


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"jerk_periods": "two"}, "jerk_periods"),
        ({"jerk_periods": 1.5}, "jerk_periods"),
        ({"jerk_periods": -1}, "jerk_periods"),
        ({"jerk_periods": 0}, "jerk_periods"),  # (0, 0) is no zero of eq. 44
        ({"delta": 1, "jerk_periods": 1}, "delta"),  # a side band needs acceleration_time_s
        ({"delta": 2}, "delta"),
        ({"max_acceleration": -5}, "max_acceleration"),
        ({"max_torque_nm": 10.0}, "max_torque_nm"),  # a mode plant defines no motor torque
        ({"target_velocity": None}, "target_velocity"),
        ({"target_velocity": 0.0}, "target_velocity"),
        ({"displacement": -5.0}, "target_velocity"),  # cruise speed of the other sign
        ({"method": "genetic"}, "method"),
        ({"optimization": {"objective": "worst_case"}}, "optimization"),  # options without method optimized
        ({"method": "optimized", "optimization": {"objective": "fastest"}}, "optimization.objective"),
        # each damping ratio is bounded in the schema (0 <= zeta < 1): the error names the element
        ({"method": "optimized", "optimization": {"damping_ratios": [1.5]}}, "optimization.damping_ratios[0]"),
        ({"frequency_uncertainty": 1.5}, "frequency_uncertainty"),
        ({"sample_period_s": 1e-6}, "sample_period_s"),  # 3e5 samples: above the test cap of 5000
        ({"horizon_s": 0.1}, "horizon_s"),  # before the end of the ramp (0.175 s)
        ({"sensitivity": {"count": 3000, "damping_ratios": [0, 0.1]}}, "sensitivity.count"),  # 6000 > 5000
        ({"colour": "red"}, "colour"),
        ({"plant": {"kind": "mode", "natural_frequency_hz": -1}}, "plant.natural_frequency_hz"),
    ],
)
def test_invalid_requests(client, change, field):
    assert_problem(client.post(PATH, json={**SEC3, **change}), 422, field)


def test_without_an_acceleration_limit_a_stap_does_not_apply(client):
    # Eq. (21) needs a_Max (or a torque limit, eq. 19) unless t_a is fixed: the family does not apply.
    body = assert_problem(client.post(PATH, json={**SEC3, "max_acceleration": None}), 422, slug="not-applicable")
    assert body["field"] == "limits.max_acceleration" and "acceleration limit" in body["detail"]


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        ({"acceleration_time_s": 0.02}, "acceleration_time_s", "eq. 72"),
        ({"acceleration_time_s": 0.1}, "acceleration_time_s", "t_a,min"),
        ({"acceleration_time_s": 0.18, "jerk_periods": 4}, "jerk_periods", "eq. 9"),  # t_j = 0.1 > t_a/2
        ({"target_velocity": 1e9, "max_acceleration": 1e-3}, "max_acceleration", "beyond"),  # t_a,min = 1e12 s
    ],
)
def test_infeasible_requests(client, change, field, words):
    problem = assert_problem(client.post(PATH, json={**SEC3, **change}), 422, slug="infeasible")
    assert problem["field"] == field and words in problem["detail"]


def test_no_transfer_function_without_a_mode(client):
    plant = {"kind": "transfer_function", "numerator": [1.0], "denominator": [1.0, 3.0, 2.0]}  # real poles only
    assert_problem(client.post(PATH, json={**SEC3, "plant": plant}), 422, "plant")


def test_openapi_documents_the_route(client):
    schema = client.get("/openapi.json").json()
    operation = schema["paths"]["/v1/profiles/stap"]["post"]
    assert set(operation["requestBody"]["content"]["application/json"]["examples"]) == set(EXAMPLES)
    assert {"422", "503", "504"} <= set(operation["responses"])
