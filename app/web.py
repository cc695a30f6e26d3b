"""The browser side: dashboard page, its static files, plotly.js and the API docs, all local.

Nothing is fetched from a CDN, so the service works without internet. plotly.js is a bundle of
plotly's core and heatmap (1.1 MB: every trace type the dashboard draws) or plotly's partial
"cartesian" bundle (1.5 MB) when it was built or installed from npm at install time
(scripts/serve.sh, scripts/test.sh, the Dockerfile), else the full bundle (4.8 MB) of the
installed ``plotly`` package; Swagger UI comes from ``swagger-ui-bundle``.
"""

from __future__ import annotations

import functools
import gzip
import hashlib
import importlib.resources
import logging
import re
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


log = logging.getLogger(__name__)


def plotly_js_path() -> Path:
    """``plotly.min.js`` shipped inside the installed plotly package (the full bundle)."""
    return Path(str(importlib.resources.files("plotly") / "package_data" / "plotly.min.js"))


def plotly_js_version() -> str:
    """The version of plotly.js the installed plotly package ships (e.g. ``4.1.1``)."""
    import plotly.offline

    return str(plotly.offline.get_plotlyjs_version())


def bundle_version(path: Path) -> str | None:
    """The plotly.js version a bundle's banner names (``plotly.js (cartesian - minified)
    v4.1.1``), or None when the file is missing or has no such banner."""
    try:
        with path.open("rb") as f:
            head = f.read(400).decode("utf-8", "replace")
    except OSError:
        return None
    m = re.search(r"plotly\.js\b[^\n]*? v(\d+\.\d+\.\d+\S*)", head)
    return m.group(1) if m else None


IMMUTABLE_CACHE = "public, max-age=31536000, immutable"
COMPILE_HINT = b"//# allFunctionsCalledOnLoad\n"
"""V8's explicit compile hint (chromium >= 136), put before plotly.js as served: V8 compiles
all its functions while the script streams in, on a background thread, instead of lazily on
the main thread during its evaluation and the first chart's draw, which a cold first visit
waits for (docs/benchmarks.md). Other browsers read a comment."""
PLOTLY_SRC_META = '<meta name="plotly-src" content="/static/vendor/plotly.min.js">'
"""The line of ``static/index.html`` that tells the dashboard where plotly.js is; the page
served at ``/`` names the versioned (immutable) URL there instead."""


@dataclass
class PlotlyBundle:
    """plotly.js as served: its file, flavour (``""`` for the full bundle, ``"cartesian"`` for
    the partial one), version, strong ETag and gzip-compressed bytes (made once, ~0.3 s: the
    full 4.8 MB become ~1.4 MB, the partial 1.5 MB ~0.5 MB)."""

    path: Path
    version: str
    flavour: str = ""

    def __post_init__(self) -> None:
        self._lock = threading.Lock()

    @property
    def url(self) -> str:
        """The versioned URL: another plotly.js version or flavour gives another URL, so it
        may be cached forever (``immutable``)."""
        name = f"plotly-{self.flavour}" if self.flavour else "plotly"
        return f"/static/vendor/{name}-{self.version}.min.js"

    @cached_property
    def raw(self) -> bytes:
        return COMPILE_HINT + self.path.read_bytes()

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


BUNDLE_FLAVOURS = ("dashboard", "cartesian")
"""The smaller plotly.js bundles, in the order they are preferred, each served when installed
(scripts/_plotly.sh) at the plotly package's plotly.js version: "dashboard", plotly's core and
heatmap (scripts/plotly-dashboard.js, 1.1 MB), and "cartesian", plotly's partial bundle (npm
``plotly.js-cartesian-dist-min``, 1.5 MB: scatter, heatmap, bar, box, contour, histogram,
pie, ...). Both cover every chart of the dashboard, which uses only SVG traces (plots.js)."""


@functools.cache
def plotly_bundle(*candidates: Path) -> PlotlyBundle:
    """The plotly.js bundle to serve: the first of ``candidates`` (one per flavour of
    ``BUNDLE_FLAVOURS``) installed and of the plotly package's plotly.js version (the one the
    dashboard is written and tested against), else the package's full bundle. One per process
    and paths (the apps of a process share its compressed bytes), compressed in a background
    thread from the first call on, so that the first chart does not wait for it.

    Its load time is what a first visit waits for: chromium evaluates the full bundle in ~4 s
    on a loaded 2-core machine, the cartesian one in ~1 s and the dashboard's in ~0.5 s
    (docs/benchmarks.md)."""
    version = plotly_js_version()
    for path, flavour in zip(candidates, BUNDLE_FLAVOURS, strict=True):
        found = bundle_version(path)
        if found == version:
            bundle = PlotlyBundle(path, version, flavour=flavour)
            break
        if path.exists():
            log.warning(
                "%s is plotly.js %s, not %s (the plotly package's): not served; "
                "scripts/serve.sh installs the matching one",
                path, found, version,
            )  # fmt: skip
    else:
        bundle = PlotlyBundle(plotly_js_path(), version)
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
    bundle = plotly_bundle(settings.plotly_dashboard_js, settings.plotly_partial_js)

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
