"""POST /v1/programs over HTTP: the answer's blocks against the core and closed forms, the CSV cam table, the
NDJSON progress and the inputs refused (a 422 naming the field and index)."""

from __future__ import annotations

import copy
import io
import re
from typing import Any

import numpy as np
import orjson
import pytest
from fastapi.testclient import TestClient

from app.examples.programs import EXAMPLES

LINE = EXAMPLES["straight_line"]["value"]


def test_the_straight_line_example_is_still_at_every_stop_and_adds_up(client: TestClient) -> None:
    """Every stop's residual is round-off (the designs cancel every mode; exact simulation); the cycle time is the
    moves and dwells end to end; the path's limits are the axes' over |u_i| (u = (3, 1) / sqrt(10))."""
    answer = client.post("/v1/programs", json=LINE)
    assert answer.status_code == 200, answer.text
    body = answer.json()
    moves = body["moves"]
    assert body["cycle_time_s"] == pytest.approx(sum(m["duration_s"] + m["dwell_s"] for m in moves), rel=1e-12)
    assert moves[1]["start_s"] == pytest.approx(moves[0]["duration_s"] + 0.2, rel=1e-12)
    u = np.array([3.0, 1.0]) / np.sqrt(10.0)
    assert moves[0]["path"]["max_velocity"] == pytest.approx(min(1.0 / u[0], 0.8 / u[1]), rel=1e-12)
    assert moves[0]["path"]["length"] == pytest.approx(np.hypot(0.3, 0.1), rel=1e-12)
    limits = {a["name"]: a["limits"] for a in LINE["axes"]}
    for move in moves:
        for name, axis in move["axes"].items():
            assert axis["stop_residual_fraction"] < 1e-12
            for quantity in ("velocity", "acceleration"):  # each axis within its own limits (1e-9: round-off)
                assert axis["metrics"][f"peak_{quantity}"] <= limits[name][f"max_{quantity}"] * (1 + 1e-9)
    # the profile ends at the last stop and the recipes are all there, none shorter than a time-optimal cycle
    # of synchronized moves would allow by more than the straight line's price (both modes on one path)
    assert body["axes"]["x"]["profile"]["position"][-1] == pytest.approx(0.0, abs=1e-12)
    assert [r["method"] for r in body["comparison"]] == ["ruckig_zv", "ruckig_zvd", "klipper_mzv", "klipper_ei"]
    assert all(r["cycle_time_ratio"] > 0.9 for r in body["comparison"])


def test_the_cam_table_is_the_profile_on_a_uniform_grid(client: TestClient) -> None:
    """format=csv: time_s = k * period exactly, one column per axis, each the JSON profile's position where the
    two grids meet (the profile's samples are the same exact commands)."""
    table = client.post("/v1/programs?format=csv", json=LINE)
    assert table.status_code == 200 and table.headers["content-type"].startswith("text/csv")
    lines = table.text.splitlines()
    assert lines[0].startswith("# machine program") and lines[1] == "time_s,x,y"
    values = np.loadtxt(io.StringIO("\n".join(lines[2:])), delimiter=",")
    period = float(values[1, 0] - values[0, 0])
    assert np.allclose(values[:, 0], np.arange(values.shape[0]) * period, rtol=0, atol=1e-12)
    profile = client.post("/v1/programs", json=LINE).json()["axes"]
    for column, name in ((1, "x"), (2, "y")):
        t = np.asarray(profile[name]["profile"]["time_s"])
        p = np.asarray(profile[name]["profile"]["position"])
        common, a, b = np.intersect1d(np.round(values[:, 0], 12), np.round(t, 12), return_indices=True)
        assert common.size > 100
        assert np.max(np.abs(values[a, column] - p[b])) <= 1e-12


def test_ndjson_reports_each_move_then_the_program(client: TestClient) -> None:
    answer = client.post("/v1/programs?format=ndjson", json=LINE)
    assert answer.status_code == 200 and answer.headers["content-type"].startswith("application/x-ndjson")
    lines = [orjson.loads(x) for x in answer.content.splitlines()]
    assert [x["line"] for x in lines] == ["move", "move", "program"]
    assert sorted(x["index"] for x in lines[:2]) == [0, 1] and lines[-1]["cycle_time_s"] > 0


def _with(change: Any) -> dict[str, Any]:
    body = copy.deepcopy(LINE)
    change(body)
    return body


def _table(body: dict[str, Any], ats: list[float]) -> None:
    body["axes"][1]["plant_table"] = {
        "coordinate": "x",
        "points": [{"at": a, "plant": {"kind": "mode", "natural_frequency_hz": 7.0 + a}} for a in ats],
    }
    del body["axes"][1]["plant"]


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        (lambda b: b["axes"][1].update(name="x"), "axes[1].name", "names axes[0]"),
        (lambda b: b["moves"][0]["target"].pop("y"), "moves[0].target", "missing axes y"),
        (lambda b: b["moves"][1]["target"].update(z=0.0), "moves[1].target", "unknown axes z"),
        (lambda b: b["start"].update(z=0.0), "start", "unknown axes z"),
        (lambda b: _table(b, [0.0, 0.2, 0.1]), "axes[1].plant_table.points[2].at", "strictly increasing"),
        (lambda b: _table(b, [0.0, 0.2]), "moves[0].target.x", "outside axes[1].plant_table's range"),
        (lambda b: b["axes"][0].pop("plant"), "axes[0].plant", "plant or plant_table"),
    ],
)
def test_bad_programs_are_a_422_naming_the_field(client: TestClient, change: Any, field: str, words: str) -> None:
    answer = client.post("/v1/programs", json=_with(change))
    assert answer.status_code == 422, answer.text
    problem = answer.json()
    assert problem["field"] == field and words in problem["detail"], problem


def test_the_same_program_on_a_local_dask_cluster_gives_the_same_answer() -> None:
    """The moves designed on a Dask LocalCluster (as VIBFREE_DASK_SCHEDULER runs them) and here: the same answer,
    every number (only the reported wall times differ: solve_time_s)."""
    distributed = pytest.importorskip("distributed")
    from app.schemas.programs import ProgramIn
    from app.services import programs as use_case
    from app.services.sweeps import executor_for
    from app.settings import Settings
    from runtime.executor import InlineExecutor
    from tests import aio

    body = ProgramIn.model_validate(LINE)
    here = InlineExecutor()

    async def on(address: str | None) -> dict[str, Any]:
        async with executor_for(address, here, 1) as (executor, capacity):
            answer, _ = await use_case.answer(body, Settings(), executor, capacity)
        return answer

    local = aio.run(on(None))
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40
    ) as cluster:
        remote = aio.run(on(cluster.scheduler_address))

    def numbers(answer: dict[str, Any]) -> bytes:
        text = orjson.dumps(answer, option=orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_SORT_KEYS)
        return re.sub(rb'"solve_time_s":[^,}]+', b"", text)

    assert numbers(remote) == numbers(local)


def test_a_payload_table_over_http(client: TestClient) -> None:
    """Y's plant over a payload picked at stop 0: the answer names the payload's plant in each move's design and
    every stop is still; a payload outside the table is a 422 naming where it was given."""
    body = copy.deepcopy(LINE)
    body["axes"][1]["plant_table"] = {
        "coordinate": "payload_kg",
        "points": [
            {"at": 0.0, "plant": {"kind": "mode", "natural_frequency_hz": 7.0, "damping_ratio": 0.02}},
            {"at": 2.0, "plant": {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": 0.02}},
        ],
    }
    body["parameters"] = {"payload_kg": 0.0}
    body["moves"][1]["parameters"] = {"payload_kg": 1.0}
    answer = client.post("/v1/programs", json=body)
    assert answer.status_code == 200, answer.text
    moves = answer.json()["moves"]
    assert all(a["stop_residual_fraction"] < 1e-11 for m in moves for a in m["axes"].values())
    modes = [m["axes"]["y"]["design"]["modes"][0]["natural_frequency_hz"] for m in moves[1:]]
    assert modes == pytest.approx([6.0], rel=1e-12)  # 7 Hz less 1 Hz a kilogram (the table's line)
    body["moves"][1]["parameters"] = {"payload_kg": 3.0}
    refused = client.post("/v1/programs", json=body)
    assert refused.status_code == 422 and refused.json()["field"] == "moves[1].parameters.payload_kg", refused.text
