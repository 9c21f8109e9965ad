"""POST /v1/identify with a printer's files: Klipper's accelerometer record (a resonance test, a knock) and its
resonance CSV, and ``target`` (the firmware's shaper).

The records are tests/printer_records.py's: the issue's axis (42 Hz zeta 0.07 and 71 Hz zeta 0.10), measured at
1600 Hz (Klipper's lis2dw rate: the test client's 2 MiB body limit) with 150 mm/s^2 of noise, printed as Klipper
prints them. Klipper's criteria themselves are checked against Klipper's code in
tests/optim/test_klipper_calibration.py; here, that the answer carries them, and that every format of the same
measurement gives the same shaper.
"""

from __future__ import annotations

import numpy as np
import orjson
import pytest

from optim.families.input_shaped import calibration as cal
from tests.app.test_errors import assert_problem
from tests.printer_records import AXIS, chirp_switches, held_record, knock, psd_csv, raw_csv, raw_record, rrf_csv

URL = "/v1/identify"
CSV = {"content-type": "text/csv"}
RATE_HZ = 1600.0


FLAT_PSD = "freq,psd_xyz\n" + "\n".join(f"{k * 1.5625:.1f},1e3" for k in range(1, 128)) + "\n"  # Klipper's bins
SWEEP = {"sweep_min_freq": 35.0, "sweep_max_freq": 80.0, "sweep_hz_per_sec": 2.0, "sweeping_period": 0.0}


@pytest.fixture(scope="module")
def sweep() -> np.ndarray:
    """A 35-80 Hz resonance test at 2 Hz/s (Klipper's fastest) without the sweeping overlay (SWEEP: 22.5 s, 36,000
    rows)."""
    switches = chirp_switches(35.0, 80.0, hz_per_sec=2.0)
    return np.round(held_record(switches, np.random.default_rng(7), rate_hz=RATE_HZ), 6)


def _post(client, text: str, **params) -> dict:
    response = client.post(URL, content=text, headers=CSV, params=params)
    assert response.status_code == 200, response.text
    return response.json()


def test_a_resonance_test_is_answered_from_its_spectrum_with_klippers_shaper(client, sweep):
    body = _post(client, raw_csv(sweep), target="klipper", **SWEEP)
    assert (body["format"], body["excitation"]) == ("klipper_raw", "sweep")
    peaks = [p["frequency_hz"] for p in body["peaks"]]
    assert peaks == pytest.approx([42.0, 71.0], abs=1.6)  # within a 1.5625 Hz bin
    # the modes fitted with the test as the excitation (the 43.47 Hz / zeta 0.0087 was a free-decay fit)
    for mode, (f, zeta, _) in zip(body["modes"], AXIS, strict=True):
        assert mode["natural_frequency_ci_hz"][0] <= f <= mode["natural_frequency_ci_hz"][1]
        assert mode["damping_ratio_ci"][0] <= zeta <= mode["damping_ratio_ci"][1]
    assert body["warnings"] == [] and body["fit"]["reduced_chi_squared"] < 1.5
    recommendation = body["recommendation"]
    assert "95 % interval of the 42" in recommendation["robust_over"]["source"]
    shaper, klipper = recommendation["shaper"], recommendation["klipper_calibration"]
    assert recommendation["dominates_klipper"] is True
    assert recommendation["remaining_vibration_percent"] <= klipper["remaining_vibration_percent"]
    assert recommendation["max_acceleration"] >= klipper["max_acceleration"] * (1 - 1e-12)
    assert recommendation["robust_remaining_vibration_percent"] >= recommendation["remaining_vibration_percent"]
    section = recommendation["firmware"]["klipper"]["section"]
    assert f"shaper_type_x: {shaper['type']}\n" in section and f"shaper_freq_x: {shaper['frequency_hz']:g}" in section
    # the figures are the named shaper's: Klipper's criteria recomputed from the answer's own spectrum
    spectrum = body["spectrum"]
    frequency, normalized = np.array(spectrum["frequency_hz"]), np.array(spectrum["psd_normalized"])
    impulses = recommendation["firmware"]["klipper"]
    assert impulses["shaper_freq_hz"] == shaper["frequency_hz"]
    from optim.families.input_shaped.firmware import klipper_impulses

    sequence = klipper_impulses(shaper["type"], shaper["frequency_hz"], shaper["damping_ratio"])
    a, t = sequence.amplitudes[None, :], sequence.times_s[None, :]
    vibrations = cal.worst_vibrations(a, t, frequency, normalized)[0]
    assert 100 * vibrations == pytest.approx(recommendation["remaining_vibration_percent"], abs=1e-9)
    assert cal.max_acceleration(a, t, 5.0)[0] == pytest.approx(recommendation["max_acceleration"], rel=1e-12)


def test_a_resonance_tests_settings_are_read_off_its_record_when_not_stated(client, sweep):
    """The fixture's test (35-80 Hz at 2 Hz/s, no sweeping overlay) sent with no settings: its band and rate are read
    off the record's ridge, the overlay's absence is seen, and the modes' intervals hold the truth."""
    body = _post(client, raw_csv(sweep))
    ridge, overlay = body["warnings"]
    assert "read off the record's ridge: 2 Hz/s, from 35 Hz, to 80 Hz" in ridge and "sweep_max_freq" in ridge
    assert "no sweeping overlay" in overlay
    test = body["fit"]["test"]
    assert (test["min_freq"], test["max_freq"], test["hz_per_sec"], test["sweeping_period"]) == (35, 80, 2, 0)
    assert abs(test["start_s"]) < 0.05  # the record starts with the test: where the ridge passes 35 Hz
    for mode, (f, zeta, _) in zip(body["modes"], AXIS, strict=True):
        assert mode["natural_frequency_ci_hz"][0] <= f <= mode["natural_frequency_ci_hz"][1]
        assert mode["damping_ratio_ci"][0] <= zeta <= mode["damping_ratio_ci"][1]
    stated = _post(client, raw_csv(sweep), **SWEEP)  # stated, the statement is used, and nothing is read
    assert stated["warnings"] == [] and stated["fit"]["test"]["hz_per_sec"] == 2.0
    # Klipper's accelerometer starts before the test's first move: 0.5 s of rest (noise only) before it
    rest = np.column_stack([sweep[0, 0] - 0.5 + np.arange(800) / RATE_HZ, np.zeros((800, 3))])
    rest[:, 1:] += np.random.default_rng(8).normal(0.0, 150.0, (800, 3)) + np.array([0.0, 0.0, 9806.65])
    late = _post(client, raw_csv(np.round(np.vstack([rest, sweep]), 6)), **SWEEP)
    assert late["fit"]["test"]["start_s"] == pytest.approx(0.5, abs=0.05) and late["warnings"] == []
    for mode, (f, _, _) in zip(late["modes"], AXIS, strict=True):
        assert mode["natural_frequency_ci_hz"][0] <= f <= mode["natural_frequency_ci_hz"][1]


def test_klippers_resonance_csv_gives_the_raw_records_shaper(client, sweep):
    """The same measurement as Klipper's TEST_RESONANCES CSV (raw PSD, frequencies printed to 0.1 Hz, values to
    4 digits) and as SHAPER_CALIBRATE's (normalised, with the shapers' columns): the same shaper, its figures within
    the printing's rounding."""
    raw = _post(client, raw_csv(sweep), target="klipper", **SWEEP)["recommendation"]
    frequency, psd = cal.klipper_psd(sweep[:, 0], sweep[:, 1:].T)
    resonances = _post(client, psd_csv(frequency, psd), target="klipper", **SWEEP)
    calibration = _post(
        client, psd_csv(frequency, cal.normalized(frequency, psd), shapers=",shapers:,zv(60.0),mzv(42.0)"),
        target="klipper",
    )  # fmt: skip
    for body in (resonances, calibration):
        assert (body["format"], body["excitation"]) == ("klipper_psd", "spectrum")
        recommendation = body["recommendation"]
        assert recommendation["shaper"]["type"] == raw["shaper"]["type"]
        assert recommendation["shaper"]["frequency_hz"] == pytest.approx(raw["shaper"]["frequency_hz"], abs=0.41)
        vibrations = recommendation["remaining_vibration_percent"]
        assert vibrations == pytest.approx(raw["remaining_vibration_percent"], abs=0.5)
    # the file's modes, fitted with the test as the excitation, hold the truth (its rows printed to 4 digits and
    # 0.1 Hz: the intervals count both)
    for mode, (f, zeta, _) in zip(resonances["modes"], AXIS, strict=True):
        assert mode["natural_frequency_ci_hz"][0] <= f <= mode["natural_frequency_ci_hz"][1]
        assert mode["damping_ratio_ci"][0] <= zeta <= mode["damping_ratio_ci"][1]
    # normalised before printing, or after from frequencies printed to 0.1 Hz: 1 / (f + 0.1) differs by up to
    # 0.05 / 10.1 = 0.5 % from 10 Hz (below, Klipper's cut e^(1 - (10 / (f + 0.1))^2) magnifies it), plus 5e-4
    above = np.array(resonances["spectrum"]["frequency_hz"]) >= 10.0
    normalized = [np.array(b["spectrum"]["psd_normalized"])[above] for b in (calibration, resonances)]
    assert normalized[0] == pytest.approx(normalized[1], rel=6e-3)


def test_each_firmware_gets_its_own_types_and_strings(client, sweep):
    text = raw_csv(sweep)
    rrf = _post(client, text, target="reprapfirmware")["recommendation"]
    assert rrf["shaper"]["type"] in ("zvd", "zvdd", "zvddd", "mzv", "ei2", "ei3")
    assert rrf["firmware"]["reprapfirmware"]["command"].startswith(f'M593 P"{rrf["shaper"]["type"]}"')
    marlin = _post(client, text, target="marlin")["recommendation"]
    assert marlin["firmware"]["marlin"]["command"].startswith("M493 S1 X C")
    for answer in (rrf, marlin):  # each says whether it matches Klipper's pick by both criteria, and why not
        if not answer["dominates_klipper"]:
            assert "Klipper's pick" in answer["reason"]


def test_a_resonance_csv_with_a_move_gets_a_design_for_its_lowest_modes_interval(client, sweep):
    """A spectrum's modes now carry 95 % intervals: with a move, the recommended design covers the lowest one's,
    as a free decay's does (tests/app/test_identify_api.py), and the reason gives the shaper's, then the design's."""
    frequency, psd = cal.klipper_psd(sweep[:, 0], sweep[:, 1:].T)
    move = {"displacement": 0.05, "max_velocity": 0.5, "max_acceleration": 5.0}
    body = _post(client, psd_csv(frequency, psd), target="klipper", **SWEEP, **move)
    recommended, low = body["recommended"], body["modes"][0]
    assert recommended is not None, body["recommendation"]["reason"]
    f = low["natural_frequency_hz"]
    assert recommended["frequency_ratio_interval"] == pytest.approx([c / f for c in low["natural_frequency_ci_hz"]])
    assert body["recommendation"]["plant"]["natural_frequency_hz"] == f
    reason = body["recommendation"]["reason"]
    assert "Of the Klipper shapers" in reason and "; design: " in reason


def test_a_knock_is_fitted_and_its_interval_makes_the_shaper_robust(client):
    table = np.round(raw_record(knock(RATE_HZ, 2.0), np.random.default_rng(3), rate_hz=RATE_HZ), 6)
    body = _post(client, raw_csv(table), target="klipper")
    assert body["format"] == "klipper_raw" and not body["quality"]["resampled"]
    assert body["quality"]["sample_rate_hz"] == pytest.approx(RATE_HZ, rel=1e-7)
    assert [m["natural_frequency_hz"] for m in body["modes"]] == pytest.approx([42.0, 71.0], rel=0.005)
    robust = body["recommendation"]["robust_over"]
    mode = body["modes"][0]
    lo, hi = mode["natural_frequency_ci_hz"]
    f = mode["natural_frequency_hz"]
    assert robust["frequency_ratio_interval"] == pytest.approx([lo / f, hi / f])
    wider = _post(client, raw_csv(table), target="klipper", frequency_tolerance=0.1)["recommendation"]
    assert wider["robust_over"]["frequency_ratio_interval"] == pytest.approx([0.9, 1.1])
    assert wider["robust_remaining_vibration_percent"] >= body["recommendation"]["remaining_vibration_percent"]


@pytest.mark.parametrize(
    ("text", "params", "field"),
    [
        ("freq,psd_x,psd_y,psd_z,psd_xyz\n1.6,1e3,1e3,1e3,3e3\n3.1,-1e3,1e3,1e3,1e3\n", {}, "psd_x[1]"),
        ("freq,a,b\n1.6,1,2\n3.1,1,2\n", {}, "header"),
        ("#time,accel_x,accel_y,accel_z\n0,1,2,3\n0.001,1,2,3\n", {"format": "klipper_psd"}, "header"),
        ("freq,psd_xyz\n1.6,1\n3.1,2\n", {"target": "duet"}, "target"),
        ("freq,psd_xyz\n1.6,1\n3.1,2\n", {"square_corner_velocity": -1}, "square_corner_velocity"),
        ("freq,psd_xyz\n1.6,1\n3.1,2\n", {"frequency_tolerance": 0.9}, "frequency_tolerance"),
        ("freq,psd_xyz\n1.6,1\n3.1,2\n", {"max_smoothing": 0.01}, "max_smoothing"),  # Klipper's minval 0.05
        ("freq,psd_xyz\n300,1\n400,2\n", {"target": "klipper"}, "body"),  # no bin up to 200 Hz
        ("freq,psd_xyz\n0,0\n1.6,0\n3.1,0\n", {"target": "klipper"}, "body"),  # no power: nothing to shape
        ("freq,psd_xyz\n1.6,1\n3.1,2\n", {"sweep_min_freq": 50, "sweep_max_freq": 40}, "sweep_max_freq"),
        ("freq,psd_xyz\n1.6,1\n3.1,2\n", {"sweep_hz_per_sec": 3}, "sweep_hz_per_sec"),  # Klipper's maxval 2
        (FLAT_PSD, {"sweep_min_freq": 1, "sweep_max_freq": 300, "sweep_hz_per_sec": 0.1}, "sweep_hz_per_sec"),
    ],
)
def test_bad_printer_files_and_parameters_are_a_422_naming_the_field(client, text, params, field):
    assert_problem(client.post(URL, content=text, headers=CSV, params=params), 422, field)


def test_vibfree_identify_target_prints_the_firmware_section(tmp_path, capsys, sweep):
    """The issue's command: ``vibfree identify FILE --target klipper`` ends with the [input_shaper] section (and
    names Klipper's own pick beside it); in-process, the same answer as the endpoint's."""
    from vibfree import cli

    record = tmp_path / "raw_data_x.csv"
    record.write_text(raw_csv(sweep))
    assert cli.main(["identify", str(record), "--target", "klipper", "--json", str(tmp_path / "answer.json")]) == 0
    out = capsys.readouterr().out
    answer = orjson.loads((tmp_path / "answer.json").read_bytes())
    shaper = answer["recommendation"]["shaper"]
    section = f"[input_shaper]\nshaper_type_x: {shaper['type']}\nshaper_freq_x: {shaper['frequency_hz']:g}\n"
    assert section in out and out.rstrip().endswith("damping_ratio_x: 0.1")
    assert "Klipper's calibration picks" in out
    assert cli.main(["identify", str(record), "--target", "marlin"]) == 0
    assert capsys.readouterr().out.rstrip().splitlines()[-1].startswith("M493 S1 X C")


def test_reprapfirmwares_accelerometer_csv_is_read_at_its_rate_in_mm_s2(client, sweep):
    """M956's file: sample numbers, g to 3 decimals (1/256 g = 38 mm/s^2 steps, under the 150 mm/s^2 noise) and the
    rate on its last line: a knock's modes within 0.5 %, a sweep answered from its spectrum, lost samples warned of,
    a failed recording refused."""
    rate = 1344.0  # a LIS3DH's rate
    table = raw_record(knock(rate, 2.0), np.random.default_rng(4), rate_hz=rate)
    body = _post(client, rrf_csv(table, rate, overflows=2), target="reprapfirmware")
    assert body["format"] == "rrf_accelerometer" and body["quality"]["sample_rate_hz"] == pytest.approx(rate)
    assert [m["natural_frequency_hz"] for m in body["modes"]] == pytest.approx([42.0, 71.0], rel=0.005)
    assert any("overflowed 2 times" in w for w in body["warnings"])
    assert body["recommendation"]["firmware"]["reprapfirmware"]["command"].startswith("M593 P")
    spectrum = _post(client, rrf_csv(sweep, RATE_HZ))
    assert (spectrum["format"], spectrum["excitation"]) == ("rrf_accelerometer", "sweep")
    failed = "Sample,X,Y,Z\nFailed to collect data from accelerometer\n"
    assert_problem(client.post(URL, content=failed, headers=CSV), 422, "body")


def test_a_generic_record_of_a_sweep_is_not_fitted_as_a_free_decay(client, sweep):
    text = "time_s,accel_x,accel_y\n" + "\n".join(f"{t - sweep[0, 0]:.6f},{x:.3f},{y:.3f}" for t, x, y, _ in sweep)
    body = _post(client, text)
    assert (body["format"], body["excitation"]) == ("generic", "sweep")
    assert [p["frequency_hz"] for p in body["peaks"]] == pytest.approx([42.0, 71.0], abs=1.6)


def test_the_documented_klipper_csv_example_gives_a_shaper(client):
    """The OpenAPI example (app/examples/identify.py: modes at 42 and 71 Hz) with target=klipper: both peaks, and a
    shaper as fast and as quiet as Klipper's pick."""
    content = client.get("/openapi.json").json()["paths"][URL]["post"]["requestBody"]["content"]["text/csv"]
    body = _post(client, content["examples"]["klipper_resonances"]["value"], target="klipper")
    assert [p["frequency_hz"] for p in body["peaks"]] == pytest.approx([42.0, 71.0], abs=1.6)
    assert body["recommendation"]["dominates_klipper"] is True
