"""The audit's reproducers of issue 11, each once a 200 that broke a limit, missed the displacement, or
refused a move that has an answer. Each must now be a 200 within the limits and at the displacement, or
a 422 of the right type with a reason; none a 500."""

from __future__ import annotations

import pytest

from app.examples import CUSIMANO_8HZ, INCERTI_TABLE_III
from tests.app.test_pseudo_polynomial_api import FALLBACK_CASE, JERK_CASE
from tests.app.test_shapers_api import REPRODUCER as SHAPED_STEP_CASE

PP = "/v1/profiles/pseudo-polynomial"
STAP = "/v1/profiles/stap"
SHAPED = "/v1/profiles/input-shaped"

CASES = [
    pytest.param(PP, JERK_CASE, id="pp-jerk-118722"),
    pytest.param(
        STAP,
        {
            "plant": {
                "kind": "two_inertia",
                "motor_inertia_kgm2": 0.43113191982048643,
                "load_inertia_kgm2": 0.7689037090974283,
                "stiffness_nm_per_rad": 2693.50111016888,
                "damping_nms_per_rad": 26.490867301436257,
            },
            "max_torque_nm": 71.66772219485838,
            "displacement": 4.132450061901825,
            "target_velocity": 11.391022289965264,
            "jerk_periods": "auto",
            "method": "optimized",
        },
        id="stap-torque-71.6956",
    ),
    pytest.param(SHAPED, SHAPED_STEP_CASE, id="shaped-step-short-of-the-displacement"),
    pytest.param(PP, FALLBACK_CASE, id="pp-solver-failed-but-4567-fits"),
] + [
    pytest.param(
        SHAPED,
        {
            "plant": {"kind": "mode", "natural_frequency_hz": 7.3, "damping_ratio": 0.02},
            "shaper": shaper,
            "displacement": 0.4,
            "limits": {"max_velocity": 0.5, "max_acceleration": 6.0},
        },
        id=f"shaped-{shaper}-cruise-within-max-velocity",
    )
    for shaper in ("zvdd", "2hump_ei", "zv", "ei")
]

PEAKS = {
    "max_velocity": "peak_velocity",
    "max_acceleration": "peak_acceleration",
    "max_jerk": "peak_jerk",
    "max_torque_nm": "peak_motor_torque_nm",
}
LEGACY = {"max_torque_nm": "max_torque_nm", "acceleration_limit": "max_acceleration"}
# Moves with a known answer within the limits: a slower STAP, the classical 4-5-6-7 polynomial (peaks
# 2.39 < 4.18 and 73.2 < 245, its closed form sampled finely), a ramp at the limit shaped by a positive shaper.
MUST_ANSWER = (STAP, SHAPED)


@pytest.mark.parametrize(("path", "body"), CASES)
def test_audit_reproducer_is_an_honest_answer(client, path, body):
    answer = client.post(path, json=body)
    assert answer.status_code in (200, 422), answer.text
    if path in MUST_ANSWER or body is FALLBACK_CASE:
        assert answer.status_code == 200, answer.text
    if answer.status_code == 422:
        problem = answer.json()
        assert problem["type"] in ("/problems/infeasible", "/problems/not-applicable"), problem
        assert problem["detail"]
        return
    out = answer.json()
    assert out["limits_met"] is True and out["limit_violations"] == []
    limits = dict(body.get("limits", {}))
    limits.update({LEGACY[k]: v for k, v in body.items() if k in LEGACY})
    samples = {
        "max_velocity": out["profile"]["velocity"],
        "max_acceleration": out["profile"]["acceleration"],
        "max_jerk": out["profile"]["jerk"],
        "max_torque_nm": out["load"]["motor_torque_nm"],
    }
    for name, limit in limits.items():
        peak = out["metrics"][PEAKS[name]]
        assert peak is not None and peak <= limit * (1 + 1e-9), (name, peak, limit)
        # The acceptance is about the samples a drive receives: checked on them, not only on the metric.
        assert max(abs(v) for v in samples[name]) <= limit * (1 + 1e-9), name
    if path == STAP and "target_velocity" in body and "displacement" in body:
        assert out["metrics"]["peak_velocity"] <= body["target_velocity"] * (1 + 1e-9)  # the legacy cruise limit
    # At the displacement: the command ends there, to round-off of the move.
    final = out["profile"]["position"][-1] - out["profile"]["position"][0]
    assert final == pytest.approx(body["displacement"], rel=1e-9)


@pytest.mark.parametrize("limits", [{}, {"max_velocity": 2.0, "max_acceleration": 20.0}])
def test_a_plant_without_a_mode_is_not_applicable_to_the_pseudo_polynomial(client, limits):
    # Found in review: the default duration divided by the slowest period, 0 without a mode (a 500).
    plant = {"kind": "transfer_function", "numerator": [99.0], "denominator": [1.0, 20.0, 99.0]}  # poles -9, -11
    answer = client.post(PP, json={"plant": plant, "displacement": 1.0, "limits": limits})
    assert answer.status_code == 422 and answer.json()["type"] == "/problems/not-applicable", answer.text


INCERTI_COMPARE = {"plant": INCERTI_TABLE_III, "displacement": 94.24777960769379, "limits": {"max_velocity": 200.0}}


@pytest.mark.parametrize(
    ("body", "field"),
    [
        # Found trying the service: 500s from underflow (a default duration of 1e150 periods, M / J = 0).
        ({**INCERTI_COMPARE, "limits": {"max_velocity": 1e-300, "max_acceleration": 700.0}}, "limits.max_velocity"),
        ({**INCERTI_COMPARE, "limits": {"max_velocity": 200.0, "max_acceleration": 5e-324}}, "limits.max_acceleration"),
        ({**INCERTI_COMPARE, "displacement": 5e-324}, "displacement"),
        (
            {"plant": CUSIMANO_8HZ, "target_velocity": 150.0, "limits": {"max_torque_nm": 5e-324}},
            "limits.max_torque_nm",
        ),
    ],
)
def test_moves_and_limits_below_a_nanometre_are_refused_by_name(client, body, field):
    answer = client.post("/v1/compare", json=body)
    assert answer.status_code == 422 and answer.json()["field"] == field, answer.text
