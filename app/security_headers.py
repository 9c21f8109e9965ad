"""The security headers of every response: its content security policy, a docs page's by hash (CSP Level 3)."""

from __future__ import annotations

import base64
import hashlib
from collections.abc import Iterable
from html.parser import HTMLParser

#: The page and the API use only the service's own assets (uPlot sets styles through the CSSOM, which
#: style-src does not restrict; the page has no inline script or style).
CONTENT_SECURITY_POLICY = (
    "default-src 'self'; img-src 'self' data:; style-src 'self'; script-src 'self'; object-src 'none'; "
    "base-uri 'none'; form-action 'self'; frame-ancestors 'none'"
)
#: Swagger UI (/docs) and ReDoc (/redoc) are served from /static/vendor (no CDN host anywhere); FastAPI's
#: pages start them with inline code, which ``docs_content_security_policy`` allows by its sha256 and
#: nothing else; images are the bundles' own data: URIs. ReDoc builds its search worker from a blob: URL
#: (made by the page, fetched from nowhere), which worker-src allows. Its "API docs by Redocly" logo is
#: an <img> from cdn.redoc.ly: img-src blocks it and ReDoc drops the <img> (its onError), so nothing
#: is fetched from that host.
_DOCS_POLICY_TEMPLATE = (
    "default-src 'self'; script-src 'self'{scripts}; style-src 'self'{styles}; img-src 'self' data:; "
    "font-src 'self'; connect-src 'self'; worker-src 'self' blob:; object-src 'none'; base-uri 'none'; "
    "form-action 'self'; frame-ancestors 'none'"
)


class _InlineCode(HTMLParser):
    """The text of each inline ``<script>`` (one without ``src``) and each ``<style>`` of a page."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=False)
        self.scripts: list[str] = []
        self.styles: list[str] = []
        self._current: list[str] | None = None
        self._chunks: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "style" or (tag == "script" and "src" not in dict(attrs)):
            self._current = self.styles if tag == "style" else self.scripts
            self._chunks = []

    def handle_data(self, data: str) -> None:
        if self._current is not None:
            self._chunks.append(data)

    def handle_endtag(self, tag: str) -> None:
        if self._current is not None and tag in ("script", "style"):
            self._current.append("".join(self._chunks))
            self._current = None


def hash_source(text: str) -> str:
    """A CSP hash source: ``'sha256-<base64 of the digest of the UTF-8 text>'`` (CSP Level 3, Sec. 2.3.1)."""
    return "'sha256-" + base64.b64encode(hashlib.sha256(text.encode()).digest()).decode() + "'"


def docs_content_security_policy(html: str, runtime_styles: Iterable[str] = ()) -> str:
    """The policy of a docs page: the service's own assets, the page's inline scripts and styles by
    their sha256, and ``runtime_styles`` (hash sources of the ``<style>`` elements its bundle adds
    at run time); no 'unsafe-inline', so no other inline code runs."""
    parser = _InlineCode()
    parser.feed(html)
    parser.close()
    scripts = dict.fromkeys(hash_source(text) for text in parser.scripts)
    styles = dict.fromkeys([*(hash_source(text) for text in parser.styles), *runtime_styles])
    return _DOCS_POLICY_TEMPLATE.format(
        scripts="".join(" " + s for s in scripts), styles="".join(" " + s for s in styles)
    )


SECURITY_HEADERS = (
    ("x-content-type-options", "nosniff"),
    ("referrer-policy", "no-referrer"),
)
