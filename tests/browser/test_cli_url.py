"""The CLI against a running server (``--url``): the same answers as in-process (issue 14)."""

from __future__ import annotations

import orjson
import pandas as pd

from vibfree import cli

STAP = {
    "plant": {"kind": "mode", "natural_frequency_hz": 40.0},
    "target_velocity": 150.0,
    "limits": {"max_acceleration": 1000.0},
}


def test_design_over_http_equals_in_process(live_server, tmp_path, capsys):
    request = tmp_path / "request.json"
    request.write_bytes(orjson.dumps(STAP))
    outputs = {}
    for where, extra in (("http", ["--url", live_server]), ("local", [])):
        csv, answer = tmp_path / f"{where}.csv", tmp_path / f"{where}.json"
        argv = ["design", "stap", str(request), "--csv", str(csv), "--json", str(answer), "--columns", "all", *extra]
        assert cli.main(argv) == 0
        outputs[where] = (csv.read_text(), orjson.loads(answer.read_bytes()), capsys.readouterr().out)
    assert outputs["http"] == outputs["local"]
    frame = pd.read_csv(tmp_path / "http.csv")
    assert "load_position" in frame.columns and frame["time_s"].iloc[0] == 0.0


def test_a_refusal_over_http_prints_the_problem(live_server, tmp_path, capsys):
    request = tmp_path / "bad.json"
    request.write_bytes(orjson.dumps({**STAP, "limits": {"max_acceleration": -1.0}}))
    assert cli.main(["design", "stap", str(request), "--url", live_server]) == 1
    assert "limits.max_acceleration" in capsys.readouterr().err


def test_an_unreachable_server_is_a_clear_error(tmp_path, capsys):
    request = tmp_path / "request.json"
    request.write_bytes(orjson.dumps(STAP))
    assert cli.main(["design", "stap", str(request), "--url", "http://127.0.0.1:9"]) == 2
    assert "cannot reach http://127.0.0.1:9" in capsys.readouterr().err
