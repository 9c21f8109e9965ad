"""/docs (Swagger UI) and /redoc (ReDoc) render with the network blocked: every request that is not to the
test server is aborted and recorded, and the pages must still show every operation of /openapi.json,
break no Content-Security-Policy rule and throw no error. Swagger UI's "Try it out" runs against the server.

Screenshots of both pages, rendered offline, are saved for review under SCREENSHOT_DIR.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlsplit

import httpx2 as httpx
import pytest

ROOT = Path(__file__).resolve().parents[2]
SCREENSHOT_DIR = Path(os.environ.get("VIBFREE_SCREENSHOT_DIR", ROOT / "test-artifacts" / "screenshots"))
# The summary the stap router declares for POST /v1/profiles/stap (app/routers/stap.py).
STAP_SUMMARY = "Symmetric trapezoidal acceleration profile without residual vibration (Cusimano)"
# Collects every CSP violation the page reports (the securitypolicyviolation event of CSP Level 3).
RECORD_CSP_VIOLATIONS = """
window.__cspViolations = [];
document.addEventListener('securitypolicyviolation', (e) => {
  window.__cspViolations.push(e.violatedDirective + ' ' + (e.blockedURI || 'inline') + ' ' + (e.sample || ''));
});
"""


@dataclass
class Offline:
    """A page whose context lets through only requests to the test server."""

    page: object
    blocked: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    served: list[str] = field(default_factory=list)

    def violations(self) -> list[str]:
        return self.page.evaluate("window.__cspViolations")  # type: ignore[attr-defined]


@pytest.fixture
def offline(browser, live_server) -> Iterator[Offline]:
    origin = urlsplit(live_server)
    context = browser.new_context(viewport={"width": 1366, "height": 900}, base_url=live_server)
    context.add_init_script(RECORD_CSP_VIOLATIONS)
    page = context.new_page()
    state = Offline(page)

    def gate(route):
        url = urlsplit(route.request.url)
        if (url.scheme, url.netloc) == (origin.scheme, origin.netloc):
            state.served.append(url.path)
            route.continue_()
        else:
            state.blocked.append(route.request.url)
            route.abort("internetdisconnected")

    context.route("**/*", gate)
    page.on("pageerror", lambda error: state.errors.append(str(error)))
    page.on("console", lambda message: message.type == "error" and state.errors.append(message.text))
    yield state
    context.close()


@dataclass(frozen=True)
class Operation:
    method: str
    path: str
    summary: str
    tag: str
    operation_id: str


@pytest.fixture(scope="module")
def operations(live_server) -> list[Operation]:
    """Every operation the service documents, read from its /openapi.json (more than ten of them)."""
    spec = httpx.get(live_server + "/openapi.json", timeout=10).json()
    found = [
        Operation(method.upper(), path, operation["summary"], operation["tags"][0], operation["operationId"])
        for path, item in spec["paths"].items()
        for method, operation in item.items()
    ]
    assert len(found) > 10 and any(o.operation_id == "stap_profile" and o.summary == STAP_SUMMARY for o in found)
    return found


def _screenshot(page, name: str) -> None:
    SCREENSHOT_DIR.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SCREENSHOT_DIR / name, full_page=False)


def _assert_self_contained(state: Offline, allowed_violations: tuple[str, ...] = ()) -> None:
    assert state.blocked == [], f"requests to other hosts: {state.blocked}"
    assert [v for v in state.violations() if v.strip() not in allowed_violations] == [], "CSP violations"
    assert [e for e in state.errors if "Content Security Policy" not in e] == [], "errors in the page"


def test_swagger_ui_renders_every_operation_offline(offline, operations):
    page = offline.page
    page.goto("/docs")
    page.get_by_text(STAP_SUMMARY, exact=True).wait_for(timeout=30_000)
    assert page.locator(".opblock").count() == len(operations)
    for operation in operations:  # Swagger UI's block id: operations-<tag>-<operationId>
        block = page.locator(f"#operations-{operation.tag}-{operation.operation_id}")
        assert block.locator(".opblock-summary-method").inner_text() == operation.method
        # Swagger UI puts zero-width spaces after the slashes of a path (line breaks)
        assert block.locator(".opblock-summary-path").inner_text().replace("\u200b", "") == operation.path
        assert block.locator(".opblock-summary-description").inner_text() == operation.summary
    assert "/static/vendor/swagger-ui/swagger-ui-bundle.js" in offline.served
    _screenshot(page, "docs-offline.png")
    _assert_self_contained(offline)


def test_swagger_ui_try_it_out_calls_the_server(offline):
    page = offline.page
    page.goto("/docs")
    operation = page.locator("#operations-health-healthz")
    operation.locator(".opblock-summary").click()
    operation.get_by_role("button", name="Try it out").click()
    with page.expect_response(lambda response: urlsplit(response.url).path == "/healthz") as answer:
        operation.get_by_role("button", name="Execute").click()
    assert answer.value.status == 200
    live = operation.locator(".live-responses-table .response")
    live.wait_for(timeout=10_000)
    assert live.locator(".response-col_status").inner_text().strip() == "200"
    assert '"status": "ok"' in live.locator(".response-col_description").inner_text()
    live.scroll_into_view_if_needed()
    _screenshot(page, "docs-try-it-out-offline.png")
    _assert_self_contained(offline)


# ReDoc 2.5.4 shows an <img> from cdn.redoc.ly beside "API docs by Redocly" (no option removes it): the
# docs policy blocks it before any request is made, and ReDoc drops the image (its onError).
REDOCLY_LOGO_BLOCKED = "img-src https://cdn.redoc.ly/redoc/logo-mini.svg"


def test_redoc_renders_every_operation_offline(offline, operations):
    page = offline.page
    page.goto("/redoc")
    page.locator("h2", has_text=STAP_SUMMARY).first.wait_for(timeout=30_000)
    for operation in operations:  # ReDoc's section id: tag/<tag>/operation/<operationId>
        section = page.locator(f"div[id='tag/{operation.tag}/operation/{operation.operation_id}']")
        assert section.locator("h2").first.inner_text() == operation.summary
        assert page.locator(f"li[data-item-id='tag/{operation.tag}/operation/{operation.operation_id}']").count() == 1
    assert "/static/vendor/redoc/redoc.standalone.js" in offline.served
    assert page.locator("img[alt='redocly logo']").count() == 0
    _screenshot(page, "redoc-offline.png")
    # the search box works: its index lives in ReDoc's blob: worker, which the policy allows
    page.get_by_placeholder("Search...").fill("Cusimano")
    results = page.locator("[data-role='search:results'] li")
    results.filter(has_text=STAP_SUMMARY).first.wait_for(timeout=10_000)
    assert results.count() == 1  # only the stap operation names Cusimano
    _assert_self_contained(offline, allowed_violations=(REDOCLY_LOGO_BLOCKED,))
