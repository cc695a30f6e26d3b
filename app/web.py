"""The browser side: dashboard page, its static files, plotly.js and the API docs, all local.

Nothing is fetched from a CDN: plotly.js comes from the installed ``plotly`` package and
Swagger UI from ``swagger-ui-bundle``, so the service works without internet.
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path

from fastapi import FastAPI
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse
from fastapi.staticfiles import StaticFiles

from app.core.config import Settings
from app.core.errors import ApiError

STATIC_CACHE = {"Cache-Control": "public, max-age=86400"}


def plotly_js_path() -> Path:
    """``plotly.min.js`` shipped inside the installed plotly package."""
    return Path(str(importlib.resources.files("plotly") / "package_data" / "plotly.min.js"))


def swagger_ui_dir() -> Path:
    """Swagger UI's files shipped by the ``swagger-ui-bundle`` package."""
    import swagger_ui_bundle

    return Path(str(swagger_ui_bundle.swagger_ui_path))


def install_web(app: FastAPI, settings: Settings) -> None:
    """Routes for ``/``, ``/static``, ``/static/vendor/plotly.min.js`` and ``/docs``."""
    static_dir = settings.static_dir
    plotly_js = plotly_js_path()

    @app.api_route("/", methods=["GET", "HEAD"], include_in_schema=False)
    def dashboard() -> FileResponse:
        index = static_dir / "index.html"
        if not index.is_file():
            raise ApiError(404, "the dashboard is not installed (static/index.html is missing)")
        return FileResponse(index, media_type="text/html", headers={"Cache-Control": "no-cache"})

    # Registered before the /static mount so that it wins over a file of the same path.
    @app.get("/static/vendor/plotly.min.js", include_in_schema=False)
    def plotly() -> FileResponse:
        return FileResponse(plotly_js, media_type="text/javascript", headers=STATIC_CACHE)

    @app.get("/docs", include_in_schema=False)
    def docs() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=app.openapi_url or "/openapi.json",
            title=f"{app.title} - API docs",
            swagger_js_url="/docs/assets/swagger-ui-bundle.js",
            swagger_css_url="/docs/assets/swagger-ui.css",
            swagger_favicon_url="/docs/assets/favicon-32x32.png",
        )

    app.mount(
        "/docs/assets", StaticFiles(directory=swagger_ui_dir(), check_dir=False), name="docs-assets"
    )
    app.mount("/static", StaticFiles(directory=static_dir, check_dir=False), name="static")
