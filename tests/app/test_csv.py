"""The profile routes' CSV for drives (issue 14): a uniform grid t_k = k * sample_period_s exactly, values
computed at those instants, the header first, no -0.0, comments and load columns only when asked."""

from __future__ import annotations

import io
import math
import re

import numpy as np
import pandas as pd
import pytest

from app.examples import CUSIMANO_8HZ

MODE = {"kind": "mode", "natural_frequency_hz": 8.0, "damping_ratio": 0.05}
# One request per profile endpoint; the input-shaped one has a period that does not divide its impulse times
# (the old CSV held 22 distinct steps, down to 9.3 us, for such a case).
CASES = {
    "/v1/profiles/time-optimal": {
        "plant": MODE,
        "displacement": 0.12,
        "limits": {"max_velocity": 0.5, "max_acceleration": 5.0},
    },
    "/v1/profiles/pseudo-polynomial": {"plant": MODE, "displacement": 0.12, "duration_s": 0.5},
    "/v1/profiles/stap": {"plant": MODE, "target_velocity": 1.0, "limits": {"max_acceleration": 10.0}},
    "/v1/profiles/smoother": {
        "plant": MODE,
        "displacement": 0.12,
        "filters": [{"type": "harmonic"}, {"type": "harmonic"}],
    },
    "/v1/profiles/input-shaped": {
        "plant": MODE,
        "shaper": "zvd",
        "target_velocity": 1.0,
        "limits": {"max_acceleration": 10.0},
        "sample_period_s": 0.0007,
    },
}
PROFILE = ["time_s", "position", "velocity", "acceleration", "jerk"]
NEGATIVE_ZERO = re.compile(r"(^|,)-0(\.0*)?(e[-+]?\d+)?(,|$)", re.MULTILINE)


def _csv(client, path, body, **params):
    response = client.post(path, json=body, params={"format": "csv", **params})
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/csv")
    return response.text


@pytest.mark.parametrize("path", CASES)
def test_every_profile_csv_reads_with_pandas_and_numpy_defaults_on_an_exact_uniform_grid(client, path):
    text = _csv(client, path, CASES[path])
    frame = pd.read_csv(io.StringIO(text))  # pandas' defaults: the first line is the header
    assert list(frame.columns) == PROFILE
    rows = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1)  # numpy's defaults
    # pandas' default float parser is not round-trip exact (a few 1e-12 relative); numpy's is
    np.testing.assert_allclose(frame.to_numpy(), rows, rtol=1e-11, atol=0)
    np.testing.assert_array_equal(pd.read_csv(io.StringIO(text), float_precision="round_trip").to_numpy(), rows)
    t = frame["time_s"].to_numpy()
    steps = np.diff(t)
    period = steps[0]
    # Equal steps to 1e-12 relative: a written t_k is the decimal nearest k * period, so a step differs from the
    # period only by the reading's round-off, eps * t_max / period (about 2000 * 2.2e-16 at default sampling).
    assert np.max(np.abs(steps / period - 1.0)) <= 1e-12
    exact = rows[:, 0]  # t_k as written: the decimal nearest k * period
    assert exact[0] == 0.0 and np.all(exact == np.round(np.arange(t.size) * period, 12))
    assert not NEGATIVE_ZERO.search(text)
    if "sample_period_s" in CASES[path]:
        assert period == pytest.approx(CASES[path]["sample_period_s"], rel=1e-12)


@pytest.mark.parametrize("path", CASES)
def test_csv_rows_are_the_json_profile_at_its_uniform_instants(client, path):
    # Where the JSON's samples (a uniform grid plus the command's corners) hold t_k, the CSV has the same
    # numbers: both evaluate the exact command at t_k (to its own round-off, 1e-12 of the move).
    profile = {k: np.asarray(v) for k, v in client.post(path, json=CASES[path]).json()["profile"].items()}
    frame = pd.read_csv(io.StringIO(_csv(client, path, CASES[path])))
    t = frame["time_s"].to_numpy()
    at = np.clip(np.searchsorted(profile["time_s"], t - 1e-12), 0, profile["time_s"].size - 1)
    shared = np.abs(profile["time_s"][at] - t) <= 1e-12
    assert shared.mean() > 0.99
    scale = np.max(np.abs(profile["position"])) + np.max(np.abs(profile["velocity"]))
    for column in ("position", "velocity"):
        np.testing.assert_allclose(
            frame[column].to_numpy()[shared], profile[column][at][shared], rtol=0, atol=1e-12 * scale
        )


@pytest.mark.parametrize("path", CASES)
def test_load_columns_satisfy_the_mode_equation_at_every_instant(client, path):
    # An independent check that command and load are taken at the same instants: the mode's load obeys
    # y'' + 2 zeta w (y' - x') + w^2 (y - x) = 0 (G = (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2)), so the
    # columns computed at t_k must satisfy it there to round-off (a resampled or shifted column would not:
    # a 1 ms shift leaves w^2 v dt ~ 2.5 here). A jump of the command's velocity (shapers on a step) makes
    # y'' jump there; right-hand values on both sides keep the identity.
    columns = "position,velocity,load_position,load_velocity,load_acceleration,deflection"
    frame = pd.read_csv(io.StringIO(_csv(client, path, CASES[path], columns=columns)))
    assert list(frame.columns) == ["time_s", *columns.split(",")]
    w, zeta = 2 * math.pi * MODE["natural_frequency_hz"], MODE["damping_ratio"]
    x, v = frame["position"].to_numpy(), frame["velocity"].to_numpy()
    y, vy, ay = (frame[c].to_numpy() for c in ("load_position", "load_velocity", "load_acceleration"))
    residual = ay + 2 * zeta * w * (vy - v) + w * w * (y - x)
    scale = w * w * np.max(np.abs(x)) + np.max(np.abs(ay))
    assert np.max(np.abs(residual)) <= 1e-9 * scale
    # deflection = y - G(0) x, G(0) = 1; to the command's evaluation round-off (the pseudo-polynomial law's
    # sum of high powers loses about 1e-10 of the move to cancellation)
    np.testing.assert_allclose(frame["deflection"], y - x, rtol=0, atol=1e-9 * np.max(np.abs(x)))


def test_comments_only_when_asked_with_units_and_metadata(client):
    path, body = "/v1/profiles/stap", CASES["/v1/profiles/stap"]
    plain = _csv(client, path, body)
    assert "#" not in plain
    text = _csv(client, path, body, comments="true")
    comments = [line for line in text.splitlines() if line.startswith("#")]
    head = text.splitlines()[len(comments)]
    assert head == ",".join(PROFILE) and text.splitlines()[: len(comments)] == comments
    joined = "\n".join(comments)
    for expected in ("STAP profile", '"natural_frequency_hz":8.0', "sample_period_s:", "time_s in s", "design:"):
        assert expected in joined
    frame = pd.read_csv(io.StringIO(text), comment="#")
    np.testing.assert_array_equal(frame.to_numpy(), pd.read_csv(io.StringIO(plain)).to_numpy())


def test_all_columns_and_plant_specific_ones(client):
    body = {"plant": CUSIMANO_8HZ, "target_velocity": 150.0, "limits": {"max_torque_nm": 10.0}}
    frame = pd.read_csv(io.StringIO(_csv(client, "/v1/profiles/stap", body, columns="all")))
    assert list(frame.columns) == [
        *PROFILE,
        "load_position",
        "load_velocity",
        "load_acceleration",
        "deflection",
        "motor_torque_nm",
    ]
    assert frame["motor_torque_nm"].abs().max() <= 10.0 * (1 + 1e-9)  # the limit holds at the instants too
    mode = _csv(client, "/v1/profiles/stap", CASES["/v1/profiles/stap"], columns="all")
    assert "motor_torque_nm" not in mode.splitlines()[0]  # a mode plant defines no torque


@pytest.mark.parametrize(
    ("columns", "rule"),
    [("position,speed", "each column must be one of"), ("motor_torque_nm", "not defined for this plant")],
)
def test_bad_columns_are_a_422_naming_the_field(client, columns, rule):
    response = client.post(
        "/v1/profiles/stap", json=CASES["/v1/profiles/stap"], params={"format": "csv", "columns": columns}
    )
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["field"] == "columns" and rule in problem["detail"]
