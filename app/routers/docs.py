"""The API docs, Swagger UI at /docs and ReDoc at /redoc, served with no CDN and no external fetch.

FastAPI's own page builders (``fastapi.openapi.docs``), pointed at the bundles vendored under
``/static/vendor/swagger-ui`` and ``/static/vendor/redoc`` (see the README.md there), as FastAPI's
"Custom Docs UI Static Assets (Self-Hosting)" how-to does
(https://fastapi.tiangolo.com/how-to/custom-docs-ui-assets/). ReDoc gets no Google fonts; each page
carries the Content-Security-Policy that allows exactly its own inline code
(``security_headers.docs_content_security_policy``).
"""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html, get_swagger_ui_oauth2_redirect_html
from fastapi.responses import HTMLResponse

from app import security_headers

router = APIRouter(include_in_schema=False)

SWAGGER_UI = "/static/vendor/swagger-ui"
REDOC = "/static/vendor/redoc"
OAUTH2_REDIRECT_PATH = "/docs/oauth2-redirect"
#: Swagger UI's validator badge (its OnlineValidatorBadge, in the standalone layout) defaults to an image
#: from validator.swagger.io for a spec not on localhost; ``validatorUrl: null`` turns it off whatever the layout.
SWAGGER_UI_PARAMETERS = {"validatorUrl": None}


#: The <style> elements ReDoc 2.5.4 adds at run time (read from the rendered page, hashed with hashlib,
#: the same hashes Chromium reports): the empty sheet styled-components then fills through the CSSOM
#: (which style-src does not restrict), and perfect-scrollbar's stylesheet with its inline source map,
#: injected by webpack's style-loader. A new ReDoc bundle needs them checked again
#: (tests/browser/test_docs_offline.py fails on any CSP violation).
REDOC_RUNTIME_STYLES = (
    security_headers.hash_source(""),
    "'sha256-QMIg+bpjm3JdElJ388KYke01izlUW0UoNOeKjpMxdgc='",
)


def _with_policy(response: HTMLResponse, runtime_styles: tuple[str, ...] = ()) -> HTMLResponse:
    html = bytes(response.body).decode()
    response.headers["content-security-policy"] = security_headers.docs_content_security_policy(html, runtime_styles)
    return response


def _root_path(request: Request) -> str:
    """The mount point behind a proxy (``--root-path``), as FastAPI's default docs prefix their URLs."""
    return str(request.scope.get("root_path", "")).rstrip("/")


@router.get("/docs")
async def swagger_ui(request: Request) -> HTMLResponse:
    root = _root_path(request)
    app = request.app
    return _with_policy(
        get_swagger_ui_html(
            openapi_url=root + app.openapi_url,
            title=app.title + " - Swagger UI",
            swagger_js_url=f"{root}{SWAGGER_UI}/swagger-ui-bundle.js",
            swagger_css_url=f"{root}{SWAGGER_UI}/swagger-ui.css",
            swagger_favicon_url=f"{root}{SWAGGER_UI}/favicon-32x32.png",
            oauth2_redirect_url=root + OAUTH2_REDIRECT_PATH,
            init_oauth=app.swagger_ui_init_oauth,
            swagger_ui_parameters={**SWAGGER_UI_PARAMETERS, **(app.swagger_ui_parameters or {})},
        )
    )


@router.get(OAUTH2_REDIRECT_PATH)
async def swagger_ui_oauth2_redirect() -> HTMLResponse:
    return _with_policy(get_swagger_ui_oauth2_redirect_html())


@router.get("/redoc")
async def redoc(request: Request) -> HTMLResponse:
    root = _root_path(request)
    app = request.app
    return _with_policy(
        get_redoc_html(
            openapi_url=root + app.openapi_url,
            title=app.title + " - ReDoc",
            redoc_js_url=f"{root}{REDOC}/redoc.standalone.js",
            redoc_favicon_url=f"{root}{SWAGGER_UI}/favicon-32x32.png",
            with_google_fonts=False,
        ),
        REDOC_RUNTIME_STYLES,
    )
