"""Issue 11: the smoother family's design.residual_vibration means what STAP's does: the load's residual
amplitude after the command over the load's move |G(0) displacement|."""

from __future__ import annotations

import pytest

from app.examples import INCERTI_TABLE_III
from models.plants import BeltPlatformPlant

BELT = {**INCERTI_TABLE_III, "gear_ratio": 0.129}  # lambda = z r / R = 0.043 (Incerti eq. 4)
LAMBDA = 0.129 * 0.06 / 0.18


def test_residual_vibration_is_a_fraction_of_the_loads_move(client):
    # A harmonic smoother of 0.1 s, not tuned to the 4.96 Hz mode: it leaves a residual.
    body = {"plant": BELT, "displacement": 30.0, "filters": [{"type": "harmonic", "duration_s": 0.1}]}
    answer = client.post("/v1/profiles/smoother", json=body)
    assert answer.status_code == 200, answer.text
    design = answer.json()["design"]
    plant = BeltPlatformPlant(**{k: v for k, v in BELT.items() if k != "kind"})
    assert plant.dc_gain == pytest.approx(LAMBDA, rel=1e-12)
    # Independent: the closed form of the chain's residual (transfer function at the poles) over |lambda D|,
    # and the returned residual over the same load move; both describe the same free vibration.
    assert design["residual_vibration"] == pytest.approx(design["residual_fraction_of_move"], rel=1e-6)
    assert design["residual_fraction_of_move"] == pytest.approx(
        design["residual_amplitude_closed_form"] / (LAMBDA * 30.0), rel=1e-12
    )
    assert design["residual_vibration"] > 1e-4
    # The pipeline's own number: metrics.residual_amplitude (the sampled command simulated) over |lambda D|.
    assert design["residual_vibration"] == pytest.approx(
        answer.json()["metrics"]["residual_amplitude"] / (LAMBDA * 30.0), rel=1e-12
    )
