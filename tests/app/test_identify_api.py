"""POST /v1/identify with a text/csv record: modes with 95 % intervals, spectrum, quality, and the recommended design.

The record is tests/optim/test_identification_modal's synthesised accelerometer (two modes, 23 Hz zeta 0.03 and
61 Hz zeta 0.05, three axes, 2 kHz, 2 s, noise std 0.02: 20 to 34 dB SNR), so the truth is known. The JSON form
(time_s, signal) is tested, unchanged, in tests/app/test_smoothers_api.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from app.schemas.registry import REQUEST_SCHEMAS
from app.services.recommend import band_covers
from tests import aio
from tests.app.conftest import TEST_SETTINGS
from tests.app.test_errors import assert_problem
from tests.optim.test_identification_modal import NAMES, TRUTH, accelerometer_record, to_csv

URL = "/v1/identify"
CSV = {"content-type": "text/csv"}
MOVE = {"displacement": 0.05, "max_velocity": 0.5, "max_acceleration": 5.0}


@pytest.fixture(scope="module")
def record_csv() -> str:
    t, signals = accelerometer_record(seed=3)
    assert t.size <= TEST_SETTINGS.max_samples
    return to_csv(t, signals)


def test_a_csv_record_gives_both_modes_with_intervals_covering_the_truth(client, record_csv):
    response = client.post(URL, content=record_csv, headers=CSV)
    assert response.status_code == 200, response.text
    body = response.json()
    assert len(body["modes"]) == 2
    for mode, (f, zeta) in zip(body["modes"], TRUTH, strict=True):
        assert mode["natural_frequency_hz"] == pytest.approx(f, rel=0.01)  # the acceptance's 1 %
        lo, hi = mode["natural_frequency_ci_hz"]
        assert lo <= f <= hi
        lo, hi = mode["damping_ratio_ci"]
        assert lo <= zeta <= hi
    quality = body["quality"]
    assert quality["sample_rate_hz"] == pytest.approx(2000.0, rel=1e-9)
    assert quality["signals"] == list(NAMES)
    assert quality["confidence"] == 0.95
    spectrum = body["spectrum"]
    assert len(spectrum["frequency_hz"]) == len(spectrum["psd"]) <= 2049
    assert body["recommended"] is None  # no move given
    assert "displacement" in body["recommendation"]["reason"]


def test_the_recommended_request_posted_returns_a_design_whose_band_covers_the_interval(client, record_csv):
    body = client.post(URL, content=record_csv, headers=CSV, params=MOVE).json()
    recommended = body["recommended"]
    assert recommended is not None, body["recommendation"]
    interval = recommended["frequency_ratio_interval"]
    low_mode = body["modes"][0]
    f = low_mode["natural_frequency_hz"]
    assert interval == pytest.approx([c / f for c in low_mode["natural_frequency_ci_hz"]])
    # the choice: the least settling time among the candidates that cover the interval
    outcomes = body["recommendation"]["candidates"]
    covering = [o for o in outcomes if o["covers"]]
    assert covering and recommended["settling_time_s"] == min(o["settling_time_s"] for o in covering)
    assert {o["family"] for o in outcomes} >= {"time_optimal", "input_shaped", "stap", "smoother"}
    # posted as is to its endpoint, the design's own band covers the interval
    design = client.post(recommended["endpoint"], json=recommended["request"])
    assert design.status_code == 200, design.text
    design = design.json()
    assert band_covers(design["sensitivity"]["band_5_percent"], tuple(interval))
    assert design["metrics"]["settling_time_s"] == pytest.approx(recommended["settling_time_s"], rel=1e-9)
    assert design["limits_met"] is True


def test_every_candidate_request_is_valid_for_its_endpoint_schema(client, record_csv):
    body = client.post(URL, content=record_csv, headers=CSV, params={**MOVE, "max_jerk": 500.0}).json()
    assert body["recommended"] is not None
    request = body["recommended"]["request"]
    assert request["limits"] == {"max_velocity": 0.5, "max_acceleration": 5.0, "max_jerk": 500.0}
    family = body["recommended"]["family"]
    REQUEST_SCHEMAS[family].model_validate(request)  # strict schema: raises if the body is not a valid request


def test_a_csv_body_is_refused_by_the_other_routes_and_other_media_types_by_identify(client, record_csv):
    assert_problem(
        client.post("/v1/plants/analyze", content=record_csv, headers=CSV),
        415,
        "content-type",
        slug="unsupported-media-type",
    )
    problem = assert_problem(
        client.post(URL, content=record_csv, headers={"content-type": "text/plain"}),
        415,
        "content-type",
        slug="unsupported-media-type",
    )
    assert "text/csv" in problem["errors"][0]["rule"]
    spec = client.get("/openapi.json").json()["paths"][URL]["post"]["requestBody"]["content"]
    assert {"application/json", "text/csv"} <= set(spec)
    assert "biagiotti_free_vibration" in spec["application/json"]["examples"]


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("time_s,accel_x\n0,1\n0.0005,x\n", "accel_x[1]"),
        ("time_s,accel_x\n0,1\n0.0005,1,2\n", "row[1]"),
        ("time_s,accel_x\n0,1\n0,2\n", "time_s[1]"),
        ("0,1\n0.0005,2\n", "header"),
        ("time_s,accel_x\n" + "0,1\n" * (TEST_SETTINGS.identify_max_rows + 1), "body"),
    ],
)
def test_bad_csv_is_a_422_naming_the_column_and_row(client, text, field):
    assert_problem(client.post(URL, content=text, headers=CSV), 422, field)


def test_non_utf8_csv_is_a_400(client):
    assert_problem(client.post(URL, content=b"time_s,a\n0,\xff\n", headers=CSV), 400, "body", slug="malformed-body")


def test_query_parameters_are_checked_and_apply_to_csv_only(client, record_csv):
    assert_problem(
        client.post(URL, content=record_csv, headers=CSV, params={"max_acceleration": -1}), 422, "max_acceleration"
    )
    assert_problem(client.post(URL, content=record_csv, headers=CSV, params={"units": "g"}), 422, "units")
    both = {"displacement": 1.0, "target_velocity": 1.0}
    assert_problem(client.post(URL, content=record_csv, headers=CSV, params=both), 422, "target_velocity")
    t = np.arange(400) / 1000.0
    json_record = {"time_s": t.tolist(), "signal": (np.exp(-3 * t) * np.cos(60 * t)).tolist()}
    assert client.post(URL, json=json_record).status_code == 200
    assert_problem(client.post(URL, json=json_record, params=MOVE), 422, "displacement")


def test_a_known_command_column_starts_the_fit_where_the_command_ends(client):
    rng = np.random.default_rng(9)
    t = np.arange(3000) / 2000.0
    end = 0.4
    f, zeta = TRUTH[0]
    wn = 2 * np.pi * f
    free = np.exp(-zeta * wn * (t - end)) * np.cos(wn * np.sqrt(1 - zeta**2) * (t - end))
    y = np.where(t < end, 2.0 * np.sin(2 * np.pi * 3 * t), free) + 0.02 * rng.standard_normal(t.size)
    command = np.clip(t / end, 0, 1)
    text = (
        "time_s,command,load\n"
        + "\n".join(f"{a:.6f},{c:.9g},{v:.9g}" for a, c, v in zip(t, command, y, strict=True))
        + "\n"
    )
    body = client.post(URL, content=text, headers=CSV).json()
    assert body["quality"]["fit_start_source"] == "command_end"
    assert body["quality"]["fit_start_s"] == pytest.approx(end, abs=1e-3)
    assert body["quality"]["signals"] == ["load"]
    (mode,) = body["modes"]
    assert mode["natural_frequency_ci_hz"][0] <= f <= mode["natural_frequency_ci_hz"][1]


def test_the_in_process_runner_recommends_the_same_request_as_the_service(client, record_csv):
    # What the CLI runs without a server: the same candidates through optim.synthesis in-process.
    from app.schemas.identify import MeasurementParams
    from app.services.identify import identify_csv, in_process_runner

    served = client.post(URL, content=record_csv, headers=CSV, params=MOVE).json()
    local = aio.run(
        identify_csv(record_csv, MeasurementParams(**MOVE), in_process_runner(TEST_SETTINGS), max_rows=5000)
    )
    assert local["recommended"]["request"] == served["recommended"]["request"]
    assert local["recommended"]["settling_time_s"] == pytest.approx(served["recommended"]["settling_time_s"])


def test_a_body_above_the_size_limit_is_a_413(client):
    body = b"time_s,a\n" + b"0,0\n" * (TEST_SETTINGS.max_body_bytes // 4 + 1)
    assert_problem(client.post(URL, content=body, headers=CSV), 413, slug="body-too-large")


def test_the_documented_csv_example_is_a_complete_record_that_fits(client):
    content = client.get("/openapi.json").json()["paths"][URL]["post"]["requestBody"]["content"]["text/csv"]
    body = client.post(URL, content=content["examples"]["accelerometer_record"]["value"], headers=CSV).json()
    (mode,) = body["modes"]  # the example's 40 Hz, zeta 0.02 mode (app/examples/identify.py _csv_example)
    assert mode["natural_frequency_ci_hz"][0] <= 40.0 <= mode["natural_frequency_ci_hz"][1]
    assert mode["damping_ratio_ci"][0] <= 0.02 <= mode["damping_ratio_ci"][1]
