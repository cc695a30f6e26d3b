"""The browser side: dashboard page, its static files, plotly.js and the API docs, all local.

Nothing is fetched from a CDN: plotly.js comes from the installed ``plotly`` package and
Swagger UI from ``swagger-ui-bundle``, so the service works without internet.
"""

from __future__ import annotations

import functools
import gzip
import hashlib
import importlib.resources
import threading
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse, Response
from fastapi.staticfiles import StaticFiles

from app.core.config import Settings
from app.core.errors import ApiError

STATIC_CACHE = {"Cache-Control": "public, max-age=86400"}


def plotly_js_path() -> Path:
    """``plotly.min.js`` shipped inside the installed plotly package."""
    return Path(str(importlib.resources.files("plotly") / "package_data" / "plotly.min.js"))


IMMUTABLE_CACHE = "public, max-age=31536000, immutable"
PLOTLY_SRC_META = '<meta name="plotly-src" content="/static/vendor/plotly.min.js">'
"""The line of ``static/index.html`` that tells the dashboard where plotly.js is; the page
served at ``/`` names the versioned (immutable) URL there instead."""


@dataclass
class PlotlyBundle:
    """plotly.js as served: its version, strong ETag and gzip-compressed bytes (made once, on
    the first request, ~0.3 s: 4.8 MB become ~1.4 MB)."""

    path: Path

    def __post_init__(self) -> None:
        self._lock = threading.Lock()

    @cached_property
    def version(self) -> str:
        import plotly.offline

        return str(plotly.offline.get_plotlyjs_version())

    @property
    def url(self) -> str:
        """The versioned URL: a new plotly package gives a new URL, so it may be cached
        forever (``immutable``)."""
        return f"/static/vendor/plotly-{self.version}.min.js"

    @cached_property
    def raw(self) -> bytes:
        return self.path.read_bytes()

    @cached_property
    def etag(self) -> str:
        return '"' + hashlib.sha256(self.raw).hexdigest()[:32] + '"'

    @property
    def gzipped(self) -> bytes:
        with self._lock:  # compress once even when the first requests come together
            if "_gz" not in self.__dict__:
                self.__dict__["_gz"] = gzip.compress(self.raw, compresslevel=6, mtime=0)
            return bytes(self.__dict__["_gz"])

    def response(self, request: Request, cache_control: str) -> Response:
        """The bundle (gzip when the client accepts it), or 304 for a matching ETag."""
        headers = {"ETag": self.etag, "Cache-Control": cache_control, "Vary": "Accept-Encoding"}
        if self.etag in request.headers.get("if-none-match", ""):
            return Response(status_code=304, headers=headers)
        if "gzip" in request.headers.get("accept-encoding", "").lower():
            headers["Content-Encoding"] = "gzip"
            return Response(self.gzipped, media_type="text/javascript", headers=headers)
        return Response(self.raw, media_type="text/javascript", headers=headers)


DOCS_BACK_LINK = (
    "<style>.swagger-ui .info small pre, .swagger-ui .info .version-stamp pre "
    "{ background: #374151 !important; color: #fff !important; } "
    ".swagger-ui .info .url, .swagger-ui .info .base-url { color: #1f2937 !important; } "
    ".swagger-ui .opblock .opblock-summary-method { color: #111 !important; text-shadow: none; } "
    ".swagger-ui .json-schema-2020-12-expand-deep-button { color: #374151 !important; }"
    "</style>"
    '<body><nav aria-label="Back" style="padding:8px 20px;font:16px system-ui,sans-serif">'
    '<a id="docs-back" href="/">&larr; Back to the TrackProfile dashboard</a></nav>'
)


@functools.cache
def plotly_bundle() -> PlotlyBundle:
    """The process's one plotly.js bundle (every app of the process shares its compressed
    bytes), compressed in a background thread from the first call on, so that the first chart
    does not wait for it."""
    bundle = PlotlyBundle(plotly_js_path())
    threading.Thread(target=lambda: bundle.gzipped, name="plotly-gzip", daemon=True).start()
    return bundle


def swagger_ui_dir() -> Path:
    """Swagger UI's files shipped by the ``swagger-ui-bundle`` package."""
    import swagger_ui_bundle

    return Path(str(swagger_ui_bundle.swagger_ui_path))


def install_web(app: FastAPI, settings: Settings) -> None:
    """Routes for ``/``, ``/static``, plotly.js (``/static/vendor/plotly[-VERSION].min.js``)
    and ``/docs``."""
    static_dir = settings.static_dir
    bundle = plotly_bundle()

    @app.api_route("/", methods=["GET", "HEAD"], include_in_schema=False)
    def dashboard() -> HTMLResponse:
        index = static_dir / "index.html"
        if not index.is_file():
            raise ApiError(404, "the dashboard is not installed (static/index.html is missing)")
        html = index.read_text(encoding="utf-8").replace(
            PLOTLY_SRC_META, f'<meta name="plotly-src" content="{bundle.url}">'
        )
        return HTMLResponse(html, headers={"Cache-Control": "no-cache"})

    # Registered before the /static mount so that they win over a file of the same path.
    # Pages with charts load plotly.js when they need it (static/js/plots.js), by the
    # versioned URL the page names: cached for good, compressed, revalidated by ETag.
    @app.get(bundle.url, include_in_schema=False)
    def plotly_versioned(request: Request) -> Response:
        return bundle.response(request, IMMUTABLE_CACHE)

    @app.get("/static/vendor/plotly.min.js", include_in_schema=False)
    def plotly(request: Request) -> Response:
        return bundle.response(request, STATIC_CACHE["Cache-Control"])

    @app.get("/docs", include_in_schema=False)
    def docs() -> HTMLResponse:
        page = get_swagger_ui_html(
            openapi_url=app.openapi_url or "/openapi.json",
            title=f"{app.title} - API docs",
            swagger_js_url="/docs/assets/swagger-ui-bundle.js",
            swagger_css_url="/docs/assets/swagger-ui.css",
            swagger_favicon_url="/docs/assets/favicon-32x32.png",
            # Deep links put a link inside each operation's toggle button (nested
            # interactive controls, which screen readers cannot announce).
            swagger_ui_parameters={"deepLinking": False},
        )
        # A way back to the dashboard (the docs page is Swagger UI's own, without our nav),
        # the page's language, and contrast fixes of Swagger UI's grey-on-grey badges.
        html = (
            bytes(page.body)
            .decode()
            .replace("<html>", '<html lang="en">', 1)
            .replace("<body>", DOCS_BACK_LINK, 1)
        )
        return HTMLResponse(html, headers={"Cache-Control": "no-cache"})

    app.mount(
        "/docs/assets", StaticFiles(directory=swagger_ui_dir(), check_dir=False), name="docs-assets"
    )
    app.mount("/static", StaticFiles(directory=static_dir, check_dir=False), name="static")
