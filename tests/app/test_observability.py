"""Request ids, JSON logs, Prometheus metrics and security headers (app/observability.py, json_logs.py,
service_metrics.py, security_headers.py)."""

from __future__ import annotations

import base64
import hashlib
import json
import logging
import re
import shlex
import subprocess
import sys
from datetime import datetime
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from prometheus_client import CollectorRegistry, generate_latest
from prometheus_client.parser import text_string_to_metric_families

from app import json_logs, service_metrics
from app.examples import CHATLATANAGULCHAI_EQ3, INCERTI_TABLE_III
from app.main import create_app
from app.observability import ObservabilityMiddleware
from app.routers import docs
from app.security_headers import CONTENT_SECURITY_POLICY
from app.settings import Settings

ROOT = Path(__file__).resolve().parents[2]
GENERATED_ID = re.compile(r"[0-9a-f]{32}")  # uuid.uuid4().hex, what the middleware generates

# Incerti's Table III move (the README's first curl example): a pseudo-polynomial design, solved by IPOPT in a worker.
INCERTI_MOVE = {"plant": INCERTI_TABLE_III, "displacement": 94.24777960769379, "duration_s": 1.0}
# Chatlatanagulchai Sec. 4 at a = 0.05: the no-overlap condition fails, a 422 /problems/infeasible
# (the same request as tests/app/test_vocabulary.py::test_a_core_error_is_named_in_the_callers_words).
INFEASIBLE_SHAPED = {
    "plant": CHATLATANAGULCHAI_EQ3,
    "shaper": "zvd",
    "target_velocity": 1.0,
    "baseline": "modified",
    "limits": {"max_acceleration": 0.05},
}


def json_lines(text: str) -> list[dict]:
    """Every line of captured stderr must be one JSON object (the issue's criterion 1)."""
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def samples(client: TestClient) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    response = client.get("/metrics")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/plain; version=0.0.4")
    return {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in text_string_to_metric_families(response.text)
        for s in family.samples
    }


def requests_count(client: TestClient, method: str, route: str, status: str) -> float:
    key = ("vibfree_http_requests_total", (("method", method), ("route", route), ("status", status)))
    return samples(client).get(key, 0.0)


# SolverPool.stats()'s contract (keys and meaning given in the issue), distinct values to tell them apart.
POOL_STATS = {
    "workers": 4,
    "ready": 3,
    "busy": 2,
    "starting": 1,
    "queued": 5,
    "restarts": 6,
    "timeouts": 7,
    "rejected": 8,
}


class FakePool:
    """A pool with the stats() the real one is getting."""

    def stats(self) -> dict[str, int]:
        return dict(POOL_STATS)


# --- request ids and logs -------------------------------------------------------------------------


def test_a_request_id_is_echoed_and_in_the_access_line(client, capsys):
    capsys.readouterr()
    request_id = "trace-4bf92f3577b34da6.a3ce929d:0e0e4736"  # letters, digits, - . : (all allowed)
    response = client.get("/healthz", headers={"X-Request-ID": request_id})
    assert response.headers["x-request-id"] == request_id
    lines = json_lines(capsys.readouterr().err)
    (access,) = [line for line in lines if line.get("event") == "request" and line.get("request_id") == request_id]
    assert access["method"] == "GET" and access["path"] == "/healthz" and access["route"] == "/healthz"
    assert access["status"] == 200 and access["level"] == "info" and access["logger"] == "app.access"
    assert access["duration_ms"] >= 0 and access["client"]
    assert datetime.fromisoformat(access["timestamp"]).tzinfo is not None  # ISO 8601, UTC


@pytest.mark.parametrize(
    "sent",
    ["has spaces", "x" * 129, "semi;colon", "<script>", ""],  # outside 1-128 of [A-Za-z0-9-_.:]
)
def test_an_invalid_request_id_is_replaced(client, sent):
    response = client.get("/healthz", headers={"X-Request-ID": sent})
    assert GENERATED_ID.fullmatch(response.headers["x-request-id"])


def test_a_request_id_of_128_characters_is_kept_and_none_is_generated(client):
    assert client.get("/healthz", headers={"X-Request-ID": "a" * 128}).headers["x-request-id"] == "a" * 128
    first, second = (client.get("/healthz").headers["x-request-id"] for _ in range(2))
    assert GENERATED_ID.fullmatch(first) and GENERATED_ID.fullmatch(second) and first != second


def test_a_problem_carries_the_request_id(client):
    response = client.get("/no/such/path", headers={"X-Request-ID": "lost-1"})
    assert response.status_code == 404 and response.headers["content-type"] == "application/problem+json"
    assert response.headers["x-request-id"] == "lost-1"


def test_a_500_problem_carries_the_id_and_the_headers_and_its_log_line_is_json(capsys):
    # A separate app (not started: no pool) with a failing route; create_app runs a second time in
    # this process, which a global Prometheus registry would refuse (duplicated timeseries).
    app = create_app(Settings(workers=1))

    @app.get("/test/boom")
    async def boom() -> None:
        raise RuntimeError("boom")

    capsys.readouterr()
    response = TestClient(app, raise_server_exceptions=False).get("/test/boom", headers={"X-Request-ID": "boom-1"})
    assert response.status_code == 500 and response.json()["type"] == "/problems/internal-error"
    assert response.headers["x-request-id"] == "boom-1"
    assert response.headers["content-security-policy"] == CONTENT_SECURITY_POLICY
    lines = json_lines(capsys.readouterr().err)
    # The handlers (app/problem_handlers.py) log the error on the app.problems logger through the stdlib: JSON too,
    # with the bound request id and the traceback.
    (error,) = [line for line in lines if line.get("logger") == "app.problems"]
    assert error["level"] == "error" and error["request_id"] == "boom-1" and "RuntimeError: boom" in error["exception"]
    (access,) = [line for line in lines if line.get("event") == "request"]
    assert access["status"] == 500 and access["request_id"] == "boom-1"


def test_configure_logging_is_idempotent():
    json_logs.configure_logging()
    json_logs.configure_logging()
    handlers = [h for h in logging.getLogger().handlers if isinstance(h, json_logs._StderrHandler)]
    assert len(handlers) == 1
    assert logging.getLogger("runtime.pool").getEffectiveLevel() == logging.INFO  # the app's loggers show


# --- solves -----------------------------------------------------------------------------------------


def test_a_solve_is_logged_and_counted(client, capsys):
    key = ("vibfree_solves_total", (("family", "pseudo_polynomial"), ("outcome", "ok")))
    before = samples(client).get(key, 0.0)
    capsys.readouterr()
    response = client.post("/v1/profiles/pseudo-polynomial", json=INCERTI_MOVE, headers={"X-Request-ID": "solve-1"})
    assert response.status_code == 200, response.text
    solver = response.json()["solver"]
    (line,) = [line for line in json_lines(capsys.readouterr().err) if line.get("event") == "solve"]
    # the logged figures are the answer's own solver block
    assert line["family"] == "pseudo_polynomial" and line["outcome"] == "ok" and line["executor"] == "pool"
    assert line["solver_status"] == solver["status"] and line["iterations"] == solver["iterations"]
    assert line["solver_time_s"] == solver["solve_time_s"] and line["solves"] == solver["solves"]
    assert line["request_id"] == "solve-1" and line["duration_ms"] > 0
    after = samples(client)
    assert after[key] == before + 1  # one design between two scrapes
    assert after[("vibfree_solve_duration_seconds_count", (("family", "pseudo_polynomial"),))] >= 1


def test_a_failed_solve_is_logged_with_its_problem_type(client, capsys):
    key = ("vibfree_solves_total", (("family", "input_shaped"), ("outcome", "infeasible")))
    before = samples(client).get(key, 0.0)
    capsys.readouterr()
    response = client.post("/v1/profiles/input-shaped", json=INFEASIBLE_SHAPED)
    assert response.json()["type"] == "/problems/infeasible"
    (line,) = [line for line in json_lines(capsys.readouterr().err) if line.get("event") == "solve"]
    assert line["family"] == "input_shaped" and line["outcome"] == "infeasible" and line["error"]
    assert samples(client)[key] == before + 1


# --- /metrics -------------------------------------------------------------------------------------


def test_metrics_count_requests_by_route_template(client):
    before = requests_count(client, "GET", "/problems/{slug}", "200")
    unmatched = requests_count(client, "GET", "unmatched", "404")
    client.get("/problems/not-found")  # a documented problem type: 200
    client.get("/problems/infeasible")
    client.get("/nowhere/at/all")
    assert requests_count(client, "GET", "/problems/{slug}", "200") == before + 2  # the template, not the path
    assert requests_count(client, "GET", "unmatched", "404") == unmatched + 1
    families = {f.name for f in text_string_to_metric_families(client.get("/metrics").text)}
    assert {"vibfree_http_requests", "vibfree_http_request_duration_seconds", "vibfree_solves"} <= families


def test_metrics_read_the_pool_stats_at_scrape_time(client):
    # Not monkeypatch.setattr: its undo deletes an attribute of starlette's State instead of restoring it.
    real_pool = client.app.state.pool
    client.app.state.pool = FakePool()
    try:
        values = samples(client)
    finally:
        client.app.state.pool = real_pool
    stats = POOL_STATS
    for state in ("ready", "busy", "starting"):
        assert values[("vibfree_pool_workers", (("state", state),))] == stats[state]
    assert values[("vibfree_pool_configured_workers", ())] == stats["workers"]
    assert values[("vibfree_pool_queue_depth", ())] == stats["queued"]
    assert values[("vibfree_pool_restarts_total", ())] == stats["restarts"]
    assert values[("vibfree_pool_timeouts_total", ())] == stats["timeouts"]
    assert values[("vibfree_pool_rejected_total", ())] == stats["rejected"]


def test_the_pool_collector_skips_a_pool_without_stats():
    registry = CollectorRegistry()
    registry.register(service_metrics.PoolCollector(lambda: object()))
    assert "vibfree_pool" not in generate_latest(registry).decode()
    registry = CollectorRegistry()
    registry.register(service_metrics.PoolCollector(FakePool))
    names = {f.name for f in text_string_to_metric_families(generate_latest(registry).decode())}
    assert names == {
        "vibfree_pool_workers",
        "vibfree_pool_configured_workers",
        "vibfree_pool_queue_depth",
        "vibfree_pool_restarts",
        "vibfree_pool_timeouts",
        "vibfree_pool_rejected",
    }


# --- security headers -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("method", "path", "status"),
    [
        ("GET", "/", 200),
        ("GET", "/static/app.js", 200),
        ("GET", "/v1/shapers", 200),
        ("GET", "/metrics", 200),
        ("GET", "/no/such/path", 404),
        ("DELETE", "/healthz", 405),
    ],
)
def test_security_headers_on_every_response(client, method, path, status):
    response = client.request(method, path)
    assert response.status_code == status
    assert response.headers["x-content-type-options"] == "nosniff"
    assert response.headers["referrer-policy"] == "no-referrer"
    assert response.headers["content-security-policy"] == CONTENT_SECURITY_POLICY
    assert "server" not in response.headers


DOCS_PAGES = ("/docs", "/redoc", "/docs/oauth2-redirect")


def _sha256_source(text: str) -> str:
    # CSP Level 3 hash-source: 'sha256-' and the base64 of the SHA-256 digest of the element's UTF-8 text
    return "'sha256-" + base64.b64encode(hashlib.sha256(text.encode("utf-8")).digest()).decode() + "'"


def _directives(policy: str) -> dict[str, list[str]]:
    return {name: sources for name, *sources in (d.split() for d in policy.split(";"))}


@pytest.mark.parametrize("path", DOCS_PAGES)
def test_the_docs_pages_use_only_the_services_assets(client, path):
    page = client.get(path)
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert "https://" not in page.text and "http://" not in page.text  # no CDN, no Google fonts, no favicon host
    for url in re.findall(r'(?:src|href)="([^"]+)"', page.text):  # every asset it loads is served here
        assert url.startswith("/static/vendor/"), url
        asset = client.get(url)
        assert asset.status_code == 200 and asset.content, url


@pytest.mark.parametrize("path", DOCS_PAGES)
def test_the_docs_policy_allows_no_host_and_only_the_pages_own_inline_code(client, path):
    page = client.get(path)
    directives = _directives(page.headers["content-security-policy"])
    # only keywords, the service's own origin, data:/blob: and hashes: no host source, no 'unsafe-*'
    allowed = {"'self'", "'none'", "data:", "blob:"}
    for name, sources in directives.items():
        assert all(s in allowed or s.startswith("'sha256-") for s in sources), (name, sources)
    assert directives["default-src"] == ["'self'"] and directives["object-src"] == ["'none'"]
    assert directives["frame-ancestors"] == ["'none'"] and directives["base-uri"] == ["'none'"]
    # The inline code, found here with a regex (independently of the app's HTMLParser) and hashed here.
    scripts = re.findall(r"<script>(.*?)</script>", page.text, re.S)
    styles = re.findall(r"<style>(.*?)</style>", page.text, re.S)
    assert scripts or styles  # FastAPI's pages have some: the test must see them
    hashed_scripts = [s for s in directives["script-src"] if s.startswith("'sha256-")]
    assert sorted(hashed_scripts) == sorted({_sha256_source(text) for text in scripts})
    hashed_styles = {s for s in directives["style-src"] if s.startswith("'sha256-")}
    runtime = set(docs.REDOC_RUNTIME_STYLES) if path == "/redoc" else set()
    assert hashed_styles == {_sha256_source(text) for text in styles} | runtime


def test_redocs_empty_sheet_hash_is_the_sha256_of_nothing():
    # styled-components' empty <style> (filled through the CSSOM afterwards): the SHA-256 of the empty
    # string is the published e3b0c442...7852b855 (FIPS 180-4 test vector); perfect-scrollbar's sheet, the
    # other runtime style, is checked in Chromium (tests/browser/test_docs_offline.py: no CSP violation)
    empty = docs.REDOC_RUNTIME_STYLES[0].removeprefix("'sha256-").removesuffix("'")
    assert base64.b64decode(empty).hex() == "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"


def test_swagger_ui_asks_no_validator_and_starts_from_its_bundle(client):
    page = client.get("/docs").text
    assert '"validatorUrl": null' in page  # else Swagger UI shows a badge from validator.swagger.io
    assert '<script src="/static/vendor/swagger-ui/swagger-ui-bundle.js">' in page
    assert (
        "url: '/openapi.json'" in page and "oauth2RedirectUrl: window.location.origin + '/docs/oauth2-redirect'" in page
    )


def test_the_docs_follow_a_root_path():
    # behind a proxy that mounts the service under /vibfree (uvicorn --root-path), as FastAPI's own docs do
    prefixed = TestClient(create_app(Settings(workers=1)), root_path="/vibfree")  # no lifespan: no pool needed
    page = prefixed.get("/docs").text
    assert "url: '/vibfree/openapi.json'" in page
    assert '<script src="/vibfree/static/vendor/swagger-ui/swagger-ui-bundle.js">' in page


@pytest.mark.parametrize(
    ("folder", "files", "version"),
    [
        ("swagger-ui", ("swagger-ui-bundle.js", "swagger-ui.css", "favicon-32x32.png", "LICENSE", "NOTICE"), "5.35.0"),
        ("redoc", ("redoc.standalone.js", "LICENSE"), "2.5.4"),
    ],
)
def test_the_vendored_docs_bundles_carry_their_licence_and_version(folder, files, version):
    vendor = ROOT / "app" / "static" / "vendor" / folder
    for name in (*files, "README.md"):
        assert (vendor / name).is_file(), name
    assert version in (vendor / "README.md").read_text()
    bundle = vendor / files[0]
    assert f'"{version}"' in bundle.read_text()  # the bundle is the version its README names


def test_the_middleware_drops_a_server_header_the_app_sets():
    async def app(scope, receive, send):
        await send({"type": "http.response.start", "status": 200, "headers": [(b"server", b"leaky/1.0")]})
        await send({"type": "http.response.body", "body": b"ok"})

    metrics = service_metrics.ServiceMetrics(lambda: None)
    response = TestClient(ObservabilityMiddleware(app, metrics)).get("/")
    assert response.text == "ok" and "server" not in response.headers
    assert GENERATED_ID.fullmatch(response.headers["x-request-id"])


# --- how it is served -----------------------------------------------------------------------------


def serve_commands() -> list[list[str]]:
    """``make serve``'s uvicorn command (as make expands it, not run) and the one the Dockerfile's CMD
    (``vibfree serve ...``) runs, both from ``uvicorn`` on."""
    from vibfree import cli

    dry_run = subprocess.run(["make", "-n", "serve"], capture_output=True, text=True, check=True, cwd=ROOT).stdout
    (serve,) = [
        line[line.index("uvicorn app.main:app") :] for line in dry_run.splitlines() if "uvicorn app.main" in line
    ]
    dockerfile = (ROOT / "Dockerfile").read_text()
    (cmd,) = re.findall(r"^CMD (\[.*\])$", dockerfile, re.MULTILINE)
    cmd = json.loads(cmd)
    assert cmd[:2] == ["vibfree", "serve"]
    docker = cli.serve_argv(cmd[2:], processes=2)
    return [shlex.split(serve), docker[docker.index("uvicorn") :]]


def test_the_service_is_served_without_server_header_nor_uvicorns_access_log():
    for command in serve_commands():
        assert command[0] == "uvicorn"
        assert "--no-server-header" in command and "--no-access-log" in command
        assert "--timeout-keep-alive" in command


def test_every_serve_flag_exists_in_the_installed_uvicorn():
    help_text = subprocess.run(
        [sys.executable, "-m", "uvicorn", "--help"], capture_output=True, text=True, check=True, cwd=ROOT
    ).stdout
    for command in serve_commands():
        for flag in (arg for arg in command if arg.startswith("--")):
            assert re.search(rf"(^|\s){re.escape(flag)}[\s/=]", help_text), flag


def test_a_refused_content_type_is_counted_under_its_route(client):
    # JSONBodyOnly answers before routing: it names the route itself, so the metric is not "unmatched".
    before = requests_count(client, "POST", "/v1/profiles/stap", "415")
    response = client.post("/v1/profiles/stap", content=b"hello", headers={"content-type": "text/plain"})
    assert response.status_code == 415
    assert requests_count(client, "POST", "/v1/profiles/stap", "415") == before + 1
