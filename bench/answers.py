"""The service's answers to a fixed corpus, as digests: record them before a change that must not change behaviour
(issue 24's restructuring), check them after.

    python bench/answers.py --record answers.json   # before
    python bench/answers.py --check answers.json    # after: lists every answer that differs

The corpus: every named OpenAPI example of every POST operation (JSON, and ``?format=csv`` where the operation
offers CSV), ``bench/determinism.py``'s seeded random time-optimal requests (``--count``), a few invalid requests of
each operation (their problem+json bodies: the field and the rule), ``GET /v1/shapers`` queries, the problem type
pages, ``/openapi.json`` itself, and a CSV accelerometer record posted to ``/v1/identify`` alone and with a move
(its recommendation runs every candidate design). Each answer is the status, the content type and the body, JSON
bodies without their wall times (``solve_time_s``, a sweep row's ``elapsed_s``) but with their keys in the order
the service wrote them (NDJSON lines sorted), hashed (sha256). The service
runs in-process (``create_app``, its default settings, one request at a time), so the pool's workers are this
checkout's.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.determinism import TIMING_FIELDS, random_requests  # noqa: E402
from tests.app.openapi_examples import post_examples  # noqa: E402

INVALID_BODIES: tuple[dict[str, Any], ...] = (
    {},
    {"plant": {"kind": "mode", "natural_frequency_hz": -1}, "displacement": 0.1},
    {"plant": {"kind": "mode", "natural_frequency_hz": 10}, "displacement": 0.1, "target_velocity": 1.0},
    {"plant": {"kind": "mode", "natural_frequency_hz": 10}, "displacement": 0.1, "limits": {"max_velocity": 0}},
)
SHAPER_QUERIES = ("", "?damping_ratio=0.05", "?damping_ratio=0.1&vibration_tolerance=0.02", "?damping_ratio=2")
IDENTIFY_QUERIES = ("", "?displacement=0.01&max_velocity=0.5&max_acceleration=20")


def accelerometer_csv() -> bytes:
    """0.4 s at 1 kHz of an accelerometer on a 40 Hz mode (zeta 0.02) seen by x and y, gravity on z, seeded noise
    (the same record as /v1/identify's OpenAPI example, written here so that the corpus does not depend on where
    the code keeps it)."""
    import numpy as np

    t = np.arange(400) * 1e-3
    wn = 2 * np.pi * 40.0
    mode = np.exp(-0.02 * wn * t) * np.cos(wn * np.sqrt(1 - 0.02**2) * t)
    noise = 0.01 * np.random.default_rng(0).standard_normal((3, t.size))
    columns = np.vstack([t, 0.8 * mode + noise[0], 0.3 * mode + noise[1], 9.81 + noise[2]]).T
    rows = "\n".join(f"{a:.3f},{x:.4f},{y:.4f},{z:.4f}" for a, x, y, z in columns)
    return ("time_s,accel_x,accel_y,accel_z\n" + rows + "\n").encode()


CSV_HEADERS = {"content-type": "text/csv"}
WALL_TIMES = TIMING_FIELDS | {"elapsed_s"}  # a sweep row's own wall time too


def without_wall_times(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: without_wall_times(v) for k, v in value.items() if k not in WALL_TIMES}
    if isinstance(value, list):
        return [without_wall_times(v) for v in value]
    return value


def digest(status: int, content_type: str, body: bytes) -> str:
    if content_type.startswith(("application/json", "application/problem+json")):
        body = json.dumps(without_wall_times(json.loads(body))).encode()
    elif content_type.startswith("application/x-ndjson"):  # a sweep's lines come in the order the points end
        lines = [json.dumps(without_wall_times(json.loads(line))) for line in body.splitlines()]
        body = "\n".join(sorted(lines)).encode()
    return hashlib.sha256(f"{status} {content_type}\n".encode() + body).hexdigest()


def corpus(spec: dict[str, Any], count: int) -> Iterator[tuple[str, str, str, Any]]:
    """(key, method, path, body) of every request of the corpus: a JSON body, CSV bytes, or None."""
    yield "openapi", "GET", "/openapi.json", None
    for path, name, body in post_examples(spec):
        yield f"{path} {name}", "POST", path, body
        if "format" in {p["name"] for p in spec["paths"][path]["post"].get("parameters", [])}:
            yield f"{path} {name} csv", "POST", f"{path}?format=csv", body
    for index, body in enumerate(random_requests(count)):
        yield f"random time-optimal {index}", "POST", "/v1/profiles/time-optimal", body
    for path, operations in spec["paths"].items():
        if "post" in operations and not path.startswith("/test/"):
            for index, body in enumerate(INVALID_BODIES):
                yield f"{path} invalid {index}", "POST", path, body
    for query in SHAPER_QUERIES:
        yield f"shapers {query}", "GET", f"/v1/shapers{query}", None
    for slug in ("invalid-input", "infeasible", "busy", "solve-timeout", "not-applicable", "nope"):
        yield f"problem {slug}", "GET", f"/problems/{slug}", None
    for query in IDENTIFY_QUERIES:
        yield f"identify csv {query}", "POST", f"/v1/identify{query}", accelerometer_csv()


def answers(count: int) -> dict[str, str]:
    from fastapi.testclient import TestClient

    from app.main import create_app

    app = create_app()
    out: dict[str, str] = {}
    with TestClient(app) as client:
        deadline = time.monotonic() + 300.0
        while client.get("/readyz").status_code != 200:  # the pool warms up in the background
            if time.monotonic() > deadline:
                raise SystemExit("the solver workers did not become ready in 300 s")
            time.sleep(0.5)
        spec = app.openapi()
        for key, method, path, body in corpus(spec, count):
            if isinstance(body, bytes):
                response = client.request(method, path, content=body, headers=CSV_HEADERS, timeout=600)
            else:
                response = client.request(method, path, json=body, timeout=600)
            content_type = response.headers.get("content-type", "")
            out[key] = digest(response.status_code, content_type, response.content)
            print(f"{response.status_code} {key}", file=sys.stderr)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--record", type=Path)
    mode.add_argument("--check", type=Path)
    parser.add_argument("--count", type=int, default=20, help="seeded random time-optimal requests (default 20)")
    args = parser.parse_args()
    now = answers(args.count)
    if args.record is not None:
        args.record.write_text(json.dumps(now, indent=1, sort_keys=True) + "\n")
        print(f"{len(now)} answers recorded in {args.record}")
        return 0
    before = json.loads(args.check.read_text())
    differ = sorted(k for k in before.keys() & now.keys() if before[k] != now[k])
    missing, new = sorted(before.keys() - now.keys()), sorted(now.keys() - before.keys())
    for key in differ:
        print("DIFFERS", key)
    for key in missing:
        print("MISSING", key)
    for key in new:
        print("NEW", key)
    same = len(before.keys() & now.keys()) - len(differ)
    print(f"{same} of {len(before)} answers identical; {len(differ)} differ, {len(missing)} missing, {len(new)} new")
    return 1 if differ or missing else 0


if __name__ == "__main__":
    sys.exit(main())
