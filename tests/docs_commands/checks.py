"""The checks of what the documented commands answer, one per command that runs (and the python blocks' own)."""

from __future__ import annotations

import csv
import io
import json
import re
import urllib.request

import pytest

from tests.docs_commands.documented import (
    SWEEP_POINTS,
    SWEEP_REFINED,
    documented_identification_answer,
    documented_table_columns,
    matches_listing,
)
from tests.docs_commands.sandbox import Ran


def ok(ran: Ran) -> None:
    assert ran.returncode == 0, ran


def answered(ran: Ran, *kinds: str) -> None:
    ok(ran)
    assert ran.http and all(status == 200 for status, _ in ran.http), ran
    assert all(any(kind.startswith(k) for k in kinds) for _, kind in ran.http), ran


def csv_rows(text: str) -> list[list[str]]:
    return list(csv.reader(line for line in io.StringIO(text) if not line.startswith("#")))


def check_readyz_loop(ran: Ran) -> None:
    answered(ran, "application/json")


def check_table_iii(ran: Ran) -> None:
    answered(ran, "application/json")
    answer = ran.json()
    assert answer["metrics"]["motion_time_s"] == 1.0 and answer["limits_met"]
    assert answer["profile"]["position"][-1] == pytest.approx(15 * 2 * 3.141592653589793)  # 15 revolutions
    assert answer["metrics"]["percentage_vibration"] < 1e-6  # no residual vibration


def check_time_optimal_band(ran: Ran) -> None:
    answered(ran, "application/json")
    answer = ran.json()
    nominal, five, ten = answer["tradeoff"]
    assert round(nominal["duration_s"] * 1e3, 2) == 219.71 and nominal["frequency_ratio_range"] == [1.0, 1.0]
    assert round(answer["design"]["rigid_duration_s"] * 1e3, 2) == 219.09
    robustness = answer["design"]["robustness"]
    assert robustness["covers_request"] and robustness["worst_percentage_vibration"] <= 5.0
    assert robustness["requested"]["frequency_ratio_range"] == [0.9, 1.1]
    assert [row["half_width"] for row in (nominal, five, ten)] == [0, 0.05, 0.1]
    assert all(row["status"] == "ok" for row in (nominal, five, ten))


def check_table_iii_csv(ran: Ran) -> None:
    answered(ran, "text/csv")
    assert ran.written == {"table-iii.csv"}, ran.written
    header, *rows = csv_rows((ran.cwd / "table-iii.csv").read_text())
    assert header == ["time_s", "position", "velocity", "load_position"]
    assert float(rows[1][0]) == 0.002  # one row per 2 ms
    assert float(rows[-1][1]) == pytest.approx(15 * 2 * 3.141592653589793)
    assert float(rows[-1][3]) == pytest.approx(3.141592653589793, rel=1e-6)  # the platform: half a turn


def check_help(ran: Ran) -> None:
    ok(ran)
    for command in ("design", "compare", "identify", "sweep", "program", "serve"):
        assert re.search(rf"^\s+{command}\s", ran.stdout, re.M), ran


def check_design_stap_csv(ran: Ran) -> None:
    ok(ran)
    for line in ("duration  0.175 s", "settling  0.175 s", "residual ", "band 5 %"):
        assert line in ran.stdout, ran
    assert ran.written == {"out.csv"}, ran.written
    header, *rows = csv_rows((ran.cwd / "out.csv").read_text())
    assert header == ["time_s", "position", "velocity", "acceleration", "jerk"] and len(rows) > 100


def check_design_json(ran: Ran) -> None:
    ok(ran)
    answer = ran.json()
    assert {"profile", "metrics", "design"} <= set(answer) and answer["limits_met"]
    assert "duration " in ran.stderr and "settling " in ran.stderr, ran  # the summary


def check_design_by_url(ran: Ran) -> None:
    ok(ran)
    assert f"--url http://127.0.0.1:{ran.port}" in ran.command and "settling  0.175 s" in ran.stdout, ran
    text = (ran.cwd / "out.csv").read_text()
    assert text.startswith("# STAP profile") and "\n# units: " in text
    header, *_ = csv_rows(text)
    assert header[:2] == ["time_s", "position"] and {"load_position", "deflection"} <= set(header)


def check_compare(ran: Ran) -> None:
    ok(ran)
    header, *lines = ran.stdout.splitlines()
    assert header.split()[:3] == ["design", "settling", "duration"], ran
    designs = [line for line in lines if not line.startswith("unavailable")]
    assert {"time_optimal", "stap/closed_form", "input_shaped/zv"} <= {line.split()[0] for line in designs}, ran
    settling = [float(line.split()[1]) for line in designs]
    assert settling == sorted(settling), ran  # the ranking


def check_identify(ran: Ran) -> None:
    ok(ran)
    modes = [float(f) for f in re.findall(r"^mode (\S+) Hz \(95 %", ran.stdout, re.M)]
    assert [round(f) for f in modes] == [23, 61], ran
    assert "\nrecommended: " in ran.stdout and "POST /v1/profiles/" in ran.stdout, ran
    request = json.loads(ran.stdout.strip().splitlines()[-1])
    assert request["displacement"] == 0.12 and request["limits"] == {"max_velocity": 0.5, "max_acceleration": 10}


def check_sweep_table(ran: Ran) -> None:
    ok(ran)
    assert ran.written == {"table.csv"}, ran.written
    header, *rows = csv_rows((ran.cwd / "table.csv").read_text())
    assert header == ["plant.natural_frequency_hz", *documented_table_columns()]
    assert SWEEP_POINTS <= len(rows) <= SWEEP_POINTS + SWEEP_REFINED
    assert all(row[header.index("ok")] == "True" for row in rows)
    assert "table check" in ran.stdout and "100%" in ran.stderr, ran  # the check's summary; the progress bar


def check_program_cam(ran: Ran) -> None:
    """docs/programs.md's program: every stop still on every axis (its Y mode follows X: the true plant's
    residual), the cam table's columns time_s and one per axis at t_k = k * period."""
    ok(ran)
    assert ran.written == {"cam.csv"}, ran.written
    residuals = re.findall(r"residual at the stop: x (\S+), y (\S+)$", ran.stdout, re.M)
    assert len(residuals) == 3 and all(float(v) < 1e-9 for pair in residuals for v in pair), ran
    assert re.search(r"^ruckig_zvd\s+cycle", ran.stdout, re.M) and "warning" not in ran.stdout, ran
    header, *rows = csv_rows((ran.cwd / "cam.csv").read_text())
    assert header == ["time_s", "x", "y"] and len(rows) > 100
    period = float(rows[1][0])
    assert all(abs(float(r[0]) - k * period) <= 1e-12 for k, r in enumerate(rows))


def check_sweep_parquet(ran: Ran) -> None:
    import pyarrow.parquet

    ok(ran)
    assert ran.written == {"table.parquet"}, ran.written
    table = pyarrow.parquet.read_table(ran.cwd / "table.parquet")
    assert table.column_names == ["plant.natural_frequency_hz", *documented_table_columns()]
    assert SWEEP_POINTS <= table.num_rows <= SWEEP_POINTS + SWEEP_REFINED and all(table.column("ok").to_pylist())
    assert "table check" in ran.stdout, ran


def check_served(ran: Ran) -> None:
    # the page at /, the docs at /docs (the README's comment), and ready
    for path, kind in (("/", "text/html"), ("/docs", "text/html"), ("/readyz", "application/json")):
        with urllib.request.urlopen(f"http://127.0.0.1:{ran.port}{path}", timeout=10) as answer:
            assert answer.status == 200 and answer.headers["content-type"].startswith(kind), path


def check_record_written(ran: Ran) -> None:
    ok(ran)
    assert ran.written == {"record.csv"}, ran.written
    header, *rows = csv_rows((ran.cwd / "record.csv").read_text())
    assert header == ["time_s", "accel_x", "accel_y", "accel_z"] and len(rows) == 4000


def check_resonance_test_written(ran: Ran) -> None:
    ok(ran)
    assert ran.written == {"raw_data_x.csv"}, ran.written
    header, *rows = (ran.cwd / "raw_data_x.csv").read_text().splitlines()
    assert header == "#time,accel_x,accel_y,accel_z" and len(rows) == int(22.5 * 3200), (header, len(rows))


def check_klipper_section(ran: Ran) -> None:
    # the documented output: the two modes, their 95 % intervals holding the script's 42 and 71 Hz, Klipper's pick
    # and the section (mzv at 42.2 Hz on this axis)
    ok(ran)
    modes = re.findall(r"^mode \S+ Hz \(95 %: (\S+)\.\.(\S+) Hz\)", ran.stdout, re.M)
    assert len(modes) == 2 and all(
        float(lo) <= f <= float(hi) for (lo, hi), f in zip(modes, (42.0, 71.0), strict=True)
    ), ran
    assert "Klipper's calibration picks mzv at 42.2 Hz" in ran.stdout, ran
    assert ran.stdout.endswith("[input_shaper]\nshaper_type_x: mzv\nshaper_freq_x: 42.2\ndamping_ratio_x: 0.1\n"), ran


def check_identify_answer(ran: Ran) -> None:
    answered(ran, "application/json")
    answer = ran.json()
    listing = documented_identification_answer()
    assert list(listing) == list(answer)  # "shortened": every block of the answer is listed
    matches_listing(listing, answer)


def check_recommended_design(ran: Ran) -> None:
    # the identify answer's recommended.request, posted to recommended.endpoint, designs what it recommended
    answered(ran, "application/json")
    assert len(ran.http) == 2, ran  # the identification, then the design
    recommended = documented_identification_answer()["recommended"]
    assert "/v1/identify?" in ran.command and ran.command.rstrip().endswith(recommended["endpoint"]), ran
    answer = ran.json()
    assert {"profile", "design", "metrics"} <= set(answer) and answer["limits_met"], ran
    assert answer["profile"]["position"][-1] == pytest.approx(0.05)  # the displacement asked for
    matches_listing(recommended["settling_time_s"], answer["metrics"]["settling_time_s"], "settling_time_s")
    matches_listing(recommended["band_5_percent"], answer["sensitivity"]["band_5_percent"], "band_5_percent")


def check_identify_recommends(ran: Ran) -> None:
    # the command line's recommendation is the server's: the same design, the same request
    ok(ran)
    modes = [float(f) for f in re.findall(r"^mode (\S+) Hz \(95 %", ran.stdout, re.M)]
    assert [round(f) for f in modes] == [23, 61], ran
    recommended = documented_identification_answer()["recommended"]
    assert f"\nrecommended: {recommended['label']}, settling {recommended['settling_time_s']} s" in ran.stdout, ran
    assert f"POST {recommended['endpoint']}\n" in ran.stdout, ran
    request = json.loads(ran.stdout.strip().splitlines()[-1])
    matches_listing(recommended["request"], request, "request")


def check_mkdocs_serve(ran: Ran) -> None:
    assert ran.returncode == 0, ran
    assert "<title>vibfree</title>" in ran.stdout, ran.stdout[:500]


def check_mkdocs_build(ran: Ran) -> None:
    ok(ran)
    assert {"site/index.html", "site/try-it/index.html", "site/api/index.html"} <= ran.written, ran


PYTHON_SNIPPET_CHECK = """
assert round(design.answer["metrics"]["settling_time_s"], 3) == 0.175, design.answer["metrics"]
assert table.splitlines()[0] == "time_s,position,load_position", table[:200]
assert ranking and {"stap", "time_optimal"} <= {row["family"] for row in ranking}, ranking[:1]
"""

BATCH_SNIPPET_CHECK = """
assert round(durations[0], 4) == 0.2197 and durations[1] > durations[0], durations
"""

CHAIN_SNIPPET_CHECK = """
assert [d.answer["profile"]["velocity"][0] for d in chain] == [0.0, 0.2, -0.1], chain
assert all(d.answer["metrics"]["residual_amplitude"] < 1e-12 for d in chain), [d.answer["metrics"] for d in chain]
assert 1.0 < cycle_s < 3.0, cycle_s
"""

NPZ_SNIPPET_CHECK = """
assert position.dtype == np.float64 and position.size > 100 and position[0] == 0.0
assert round(meta["metrics"]["settling_time_s"], 3) == 0.175 and "profile" not in meta
"""
