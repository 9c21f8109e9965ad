"""Fast I/O (issue 15): orjson request parsing with the standard parser's contract, ``fields=``, the npz answer
and the deprecated ``load.time_s``.

Expected values come from the service's own full JSON answer of the same request (a selection or another
encoding must hold exactly the same numbers), from the response models (the allowed ``fields`` names), and
from the standard library's ``json.loads`` (the parsing contract the service had before orjson).
"""

from __future__ import annotations

import io
import json
from typing import Any

import numpy as np
import pytest

from app import problems
from app.json_bodies import JSONRoute, has_long_integer, parse_json
from app.responses import NPZ_JSON_ENTRY, NPZ_MEDIA_TYPE, field_paths
from app.schemas.simulate import SimulateResponse
from app.schemas.stap import StapOut
from tests.app.test_errors import assert_problem

MODE = {"kind": "mode", "natural_frequency_hz": 5.0, "damping_ratio": 0.02}
_T = np.linspace(0.0, 1.0, 401)
SIMULATE = {
    "plant": MODE,
    "profile": {"time_s": _T.tolist(), "velocity": (0.5 - 0.5 * np.cos(2 * np.pi * _T)).tolist()},
}
STAP = {
    "plant": {"kind": "mode", "natural_frequency_hz": 40.0},
    "target_velocity": 150.0,
    "limits": {"max_acceleration": 1000.0},
    "jerk_periods": 1,
}
JSON = {"content-type": "application/json"}


def from_npz(content: bytes) -> dict[str, Any]:
    """The answer an npz holds, as the JSON answer's nested dicts and lists (np.load without pickle)."""
    z = np.load(io.BytesIO(content))  # allow_pickle=False, numpy's default: a pickled entry would raise here
    answer: dict[str, Any] = json.loads(z[NPZ_JSON_ENTRY].tobytes())
    for name in z.files:
        if name == NPZ_JSON_ENTRY:
            continue
        *heads, last = name.split(".")
        node = answer
        for key in heads:
            node = node.setdefault(key, {})
        node[last] = z[name].tolist()
    return answer


# ---------------------------------------------------------------------------------------------- parsing


@pytest.mark.parametrize(
    "body",
    [
        b'{"a": [1, 2.5, -0.0, 1e-300, 12345678901234567]}',
        b'{"a": NaN, "b": Infinity, "c": -Infinity}',  # literals the standard parser reads
        b'{"a": 1e999}',  # beyond double range: inf for json.loads
        b'{"a": "\\ud800"}',  # a lone surrogate
        b'\xef\xbb\xbf{"a": 1}',  # a UTF-8 byte-order mark
        b'{"a": 1, "a": 2}',  # duplicated key: the last wins in both
        b'{"a": 100000000000000000000}',  # > 2**64: orjson's double, json's int (see JSONRoute)
    ],
)
def test_parse_json_reads_what_json_loads_reads(body):
    # Expected: the standard parser's value. Equal except for integers beyond 64 bits (orjson: the nearest double),
    # which the route reads again with json.loads when validation refuses them (next tests); NaN compared as text.
    expected = json.loads(body)
    got = parse_json(body)
    if body.endswith(b"100000000000000000000}"):
        assert got == {"a": float(expected["a"])} and has_long_integer(body)
        assert parse_json(body, exact_integers=True) == expected
    else:
        assert repr(got) == repr(expected)


@pytest.mark.parametrize("body", [b'{"plant": ', b"{'plant': 1}", b'{"a": [1, 2,]}', b'{"a": 01}', b""])
def test_invalid_json_raises_the_standard_parsers_error(body):
    # Expected: json.loads' own exception, message and position (the 400's rule quotes them).
    with pytest.raises(json.JSONDecodeError) as standard:
        json.loads(body)
    with pytest.raises(json.JSONDecodeError) as ours:
        parse_json(body)
    assert (ours.value.msg, ours.value.pos) == (standard.value.msg, standard.value.pos)


def test_a_malformed_body_is_the_same_400_as_before(client):
    body = b'{"plant": {"kind": "mode", "natural_frequency_hz": 5}, "profile": {"time_s": [0, 1,]}}'
    with pytest.raises(json.JSONDecodeError) as raised:
        json.loads(body)
    error = raised.value
    problem = assert_problem(client.post("/v1/simulate", content=body, headers=JSON), 400, "body", "malformed-body")
    # the rule app/problems.validation_errors writes from the standard parser's message and position
    assert problem["errors"][0]["rule"] == f"the body is not valid JSON ({error.msg} at character {error.pos})"


@pytest.mark.parametrize("token", ["NaN", "-Infinity", "1e999"])
def test_non_finite_samples_are_still_a_422_naming_the_sample(client, token):
    # orjson refuses these literals; the standard parser reads them and the model refuses them (as before).
    body = '{"plant": {"kind": "mode", "natural_frequency_hz": 5}, '
    body += '"profile": {"time_s": [0, 1, 2], "velocity": [0, %s, 1]}}'
    response = client.post("/v1/simulate", content=(body % token).encode(), headers=JSON)
    assert_problem(response, 422, "profile.velocity[1]")


def test_a_huge_integer_is_validated_as_the_standard_parser_reads_it(client):
    # 10**30 as an integer: the echo says what json.loads read (an int of 100 bits), not orjson's 1e30.
    body = b'{"plant": {"kind": "mode", "natural_frequency_hz": 1000000000000000000000000000000}}'
    problem = assert_problem(client.post("/v1/plants/analyze", content=body, headers=JSON), 422)
    assert problem["errors"][0]["value"] == f"an integer of {(10**30).bit_length()} bits"


def test_a_sweeps_base_request_echoes_a_huge_integer_as_the_standard_parser_reads_it(client):
    # The sweep's service validates its base request itself (app.problems.InvalidRequestBody): the same exact
    # re-read as a route's own validation (before, 1.2345678901234568e+22 was echoed).
    body = b'{"family": "time-optimal", "axes": [{"path": "displacement", "values": [0.1, 0.2]}], "request": {"plant": '
    body += b'{"kind": "mode", "natural_frequency_hz": 10}, "displacement": 0.1, "limits": {"max_acceleration": '
    body += b"12345678901234567890123}}}"
    problem = assert_problem(client.post("/v1/sweeps", content=body, headers=JSON), 422)
    assert problem["errors"][0]["field"] == "request.limits.max_acceleration"
    assert problem["errors"][0]["value"] == f"an integer of {(12345678901234567890123).bit_length()} bits"


def test_has_long_integer_finds_integer_tokens_only():
    # 19 digits or more in an integer token; a run of digits after a decimal point is a fraction (orjson writes
    # 1e-5 as 0.00001000010000100001) and is not one.
    assert has_long_integer(b"[1234567890123456789]") and has_long_integer(b"12345678901234567890")
    assert has_long_integer(b'{"a": -9223372036854775809}')
    assert not has_long_integer(b"[0.00001000010000100001, 1.5e-300, 123456789012345678]")


def test_every_route_with_a_body_parses_it_with_orjson(client):
    # Expected: the app's own routes (problems.api_routes), every one that reads a body.
    with_body = [route for _, route in problems.api_routes(client.app) if route.body_field is not None]
    assert len(with_body) >= 9
    assert all(isinstance(route, JSONRoute) for route in with_body), [r.path for r in with_body]


# ---------------------------------------------------------------------------------------------- fields=


def test_fields_select_blocks_and_keys(client):
    full = client.post("/v1/simulate", json=SIMULATE).json()
    part = client.post("/v1/simulate?fields=profile,load.position,metrics", json=SIMULATE).json()
    # Expected: the same blocks of the full answer, load cut to its position.
    assert part == {
        "profile": full["profile"],
        "load": {"position": full["load"]["position"]},
        "metrics": full["metrics"],
    }


def test_fields_on_a_profile_endpoint(client):
    full = client.post("/v1/profiles/stap", json=STAP).json()
    part = client.post("/v1/profiles/stap?fields=design.acceleration_time_s,load.velocity,limits_met", json=STAP)
    assert part.json() == {
        "design": {"acceleration_time_s": full["design"]["acceleration_time_s"]},
        "load": {"velocity": full["load"]["velocity"]},
        "limits_met": full["limits_met"],
    }


@pytest.mark.parametrize(
    ("fields", "mentions"),
    [
        ("profile,bogus", "the blocks are profile, load, metrics, warnings"),
        ("load.speed", "the keys within load are time_s, position, velocity"),
        ("warnings.first", "warnings has no keys"),
        (" , ", "none given"),
    ],
)
def test_unknown_fields_are_a_422_naming_fields(client, fields, mentions):
    problem = assert_problem(client.post("/v1/simulate", params={"fields": fields}, json=SIMULATE), 422, "fields")
    assert mentions in problem["errors"][0]["rule"]


def test_allowed_fields_are_the_response_models():
    # Expected: SimulateResponse's fields, and the keys of its block models.
    paths = field_paths(SimulateResponse)
    assert set(paths) >= {"profile", "profile.jerk", "load.deflection", "metrics.settling_time_s", "warnings"}
    assert "metrics.modes" in paths and "metrics.modes.natural_frequency_hz" not in paths  # a list is a leaf
    assert "design.acceleration_time_s" in field_paths(StapOut)


def test_fields_and_the_csv_table_do_not_mix(client):
    response = client.post("/v1/profiles/stap?format=csv&fields=profile", json=STAP)
    assert "columns" in assert_problem(response, 422, "fields")["errors"][0]["rule"]


def test_unknown_fields_are_refused_before_designing(client):
    # An invalid body and unknown fields: the fields' 422 is found by the Output dependency, with the body's.
    response = client.post("/v1/profiles/stap?fields=nothing", json={**STAP, "jerk_periods": -1})
    fields = {e["field"] for e in response.json()["errors"]}
    assert response.status_code == 422 and "fields" in fields


# ---------------------------------------------------------------------------------------------- load.time_s


def test_load_time_s_is_left_out_and_returned_on_request(client):
    full = client.post("/v1/simulate", json=SIMULATE).json()
    assert "time_s" not in full["load"]
    asked = client.post("/v1/simulate?fields=load.time_s,profile.time_s", json=SIMULATE).json()
    # Expected: the deprecated alias repeats the profile's grid (the simulated command's own times).
    assert asked["load"]["time_s"] == asked["profile"]["time_s"] == SIMULATE["profile"]["time_s"]


def test_load_time_s_is_documented_as_deprecated(client):
    spec = client.get("/openapi.json").json()
    time_s = spec["components"]["schemas"]["LoadOut"]["properties"]["time_s"]
    assert time_s.get("deprecated") is True and "fields=load.time_s" in time_s["description"]
    assert "time_s" not in spec["components"]["schemas"]["LoadOut"].get("required", [])


def test_input_shaped_keeps_the_load_on_the_drives_grid(client):
    # input-shaped simulates rate_limited (what the drive does): load.time_s repeats rate_limited.time_s.
    body = {"plant": MODE, "target_velocity": 0.2, "limits": {"max_acceleration": 1.0}, "shaper": "zv"}
    answer = client.post("/v1/profiles/input-shaped?fields=load.time_s,rate_limited.time_s", json=body)
    assert answer.status_code == 200, answer.text
    assert answer.json()["load"]["time_s"] == answer.json()["rate_limited"]["time_s"]
    assert "time_s" not in client.post("/v1/profiles/input-shaped", json=body).json()["load"]


# ---------------------------------------------------------------------------------------------- npz


@pytest.mark.parametrize("query", ["", "?fields=profile,load.position,metrics", "?fields=load.time_s,warnings"])
def test_npz_round_trips_to_the_json_answer(client, query):
    expected = client.post(f"/v1/simulate{query}", json=SIMULATE).json()
    response = client.post(f"/v1/simulate{query}", json=SIMULATE, headers={"accept": NPZ_MEDIA_TYPE})
    assert response.status_code == 200 and response.headers["content-type"] == NPZ_MEDIA_TYPE
    assert from_npz(response.content) == expected  # exact: float64 arrays and shortest round-trip JSON floats


def test_npz_of_a_profile_endpoint_by_format(client):
    expected = client.post("/v1/profiles/stap", json=STAP).json()
    response = client.post("/v1/profiles/stap?format=npz", json=STAP)
    z = np.load(io.BytesIO(response.content))
    assert z["profile.position"].dtype == np.float64 and "load.time_s" not in z.files
    assert from_npz(response.content) == expected


def test_json_stays_the_default_and_wins_when_listed_first(client):
    response = client.post("/v1/simulate", json=SIMULATE, headers={"accept": f"application/json, {NPZ_MEDIA_TYPE}"})
    assert response.headers["content-type"] == "application/json"
    assert (
        client.post("/v1/simulate?format=json", json=SIMULATE, headers={"accept": NPZ_MEDIA_TYPE}).headers[
            "content-type"
        ]
        == "application/json"
    )


def test_npz_and_fields_are_documented(client):
    spec = client.get("/openapi.json").json()
    for path in ("/v1/simulate", "/v1/profiles/stap", "/v1/profiles/time-optimal"):
        operation = spec["paths"][path]["post"]
        assert NPZ_MEDIA_TYPE in operation["responses"]["200"]["content"]
        names = {p["name"] for p in operation["parameters"]}
        assert {"fields", "format"} <= names
        assert "np.load(io.BytesIO(r.content))" in operation["responses"]["200"]["description"]


# ---------------------------------------------------------------------------------------------- the HTTP parser


async def tiny_app(scope: dict[str, Any], receive: Any, send: Any) -> None:
    """An ASGI app that answers 200 to any request: what the HTTP parser lets through, without the service."""
    if scope["type"] == "lifespan":
        while (await receive())["type"] != "lifespan.shutdown":
            await send({"type": "lifespan.startup.complete"})
        await send({"type": "lifespan.shutdown.complete"})
        return
    await send({"type": "http.response.start", "status": 200, "headers": [(b"content-length", b"2")]})
    await send({"type": "http.response.body", "body": b"ok"})


def _first_line(port: int, request: bytes) -> bytes:
    import socket

    with socket.create_connection(("127.0.0.1", port), timeout=20) as s:
        try:
            s.sendall(request)
            return s.recv(100).split(b"\r\n")[0]
        except ConnectionError:  # the server closed before the client finished sending: refused too
            return b"reset"


@pytest.mark.parametrize("http", ["makefile", "httptools"])
def test_a_huge_header_is_refused_by_the_served_parser_only(http):
    """The Makefile's SERVE_FLAGS (h11, 16 KiB of incomplete headers) refuse a 1 MB header; httptools (installed
    with uvicorn[standard]) takes it, and 10 MB: it has no header cap, which is why h11 stays pinned."""
    import re
    import shlex
    import socket
    import subprocess
    import sys
    import time
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    text = (root / "Makefile").read_text()
    flags = shlex.split(re.search(r"^SERVE_FLAGS \?=((?:.*\\\n)*.*)$", text, re.M).group(1).replace("\\\n", " "))
    if http == "httptools":
        at = flags.index("--h11-max-incomplete-event-size")
        flags = [f for i, f in enumerate(flags) if i not in (at, at + 1)]
        flags[flags.index("--http") + 1] = "httptools"
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    command = [sys.executable, "-m", "uvicorn", "tests.app.test_fast_io:tiny_app", "--port", str(port), *flags]
    server = subprocess.Popen(command, cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                if _first_line(port, b"GET / HTTP/1.1\r\nhost: x\r\n\r\n") == b"HTTP/1.1 200 OK":
                    break
            except OSError:
                pass
            assert time.monotonic() < deadline and server.poll() is None, "uvicorn did not start"
            time.sleep(0.2)
        huge = b"GET / HTTP/1.1\r\nhost: x\r\nx-big: " + b"a" * 1_000_000 + b"\r\n\r\n"
        answer = _first_line(port, huge)
        if http == "makefile":
            assert answer in (b"HTTP/1.1 400 Bad Request", b"reset")
        else:
            assert answer == b"HTTP/1.1 200 OK"  # no cap: the reason for the h11 pin
    finally:
        server.terminate()
        server.wait(20)
