"""The ASGI application: ``uvicorn app.main:app`` serves the API, the dashboard and the docs.

``create_app(settings)`` builds an independent instance (tests point it at their own database);
on start it applies the migrations and starts the background worker.
"""

from __future__ import annotations

import gc
import logging
import threading
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from fastapi.concurrency import run_in_threadpool
from fastapi.middleware.cors import CORSMiddleware
from fastapi.openapi.utils import get_openapi

from app import __version__
from app.api.access import AccessMiddleware, KeyRegister
from app.api.main import UPLOAD_PATHS, api_router
from app.api.openapi import (
    add_body_models,
    bounded_integers,
    errors_as_json,
    operation_id,
    security_as_configured,
)
from app.api.routes import health
from app.core import memory
from app.core.config import Settings, get_settings
from app.core.errors import install_error_handlers
from app.core.middleware import BodySizeLimitMiddleware, SecurityHeadersMiddleware
from app.db.migrate import upgrade
from app.db.session import Database
from app.schemas.runs import RunCreateJson
from app.schemas.stiffness import SurveyCreateJson
from app.services.context import AppContext
from app.services.run_lifecycle.queue import Worker
from app.web import install_web

log = logging.getLogger("app")

DESCRIPTION = """
Drive-by track monitoring. Upload run logs of an instrumented vehicle (vertical body
acceleration and pitch rate); the service back-calculates the loaded track profile along
chainage and finds soft spots (weak track support).

Units: chainage in m, levels and depths in mm (positive up: a soft spot is a dip), stiffness
loss in %, everything else SI. Errors answer `{"detail": {"message": ..., "field" | "column" |
"row" | "unit": ...}}`.
"""


class _IdleReleaseTimer(threading.Thread):
    """Asks ``IdleRelease`` once a second whether the process has been idle long enough."""

    def __init__(self, release: memory.IdleRelease) -> None:
        super().__init__(name="memory-release", daemon=True)
        self._release = release
        self._stop_event = threading.Event()

    def run(self) -> None:
        while not self._stop_event.wait(1.0):
            self._release.release_if_idle()

    def stop(self) -> None:
        self._stop_event.set()
        self.join(5.0)


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the app for ``settings`` (default: from the environment)."""
    settings = settings or get_settings()
    db = Database(settings.sqlalchemy_url)
    ctx = AppContext(settings=settings, db=db)
    keys = KeyRegister(db)
    if settings.require_api_key_for_reads and not settings.require_api_key:
        log.warning(
            "TRACKPROFILE_REQUIRE_API_KEY_FOR_READS is set without TRACKPROFILE_REQUIRE_API_KEY: "
            "API keys are required for reads and writes"
        )

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        releaser = None
        if settings.memory_release_idle_s > 0:
            memory.keep_freed_memory()
            releaser = _IdleReleaseTimer(ctx.memory)
            releaser.start()
        if settings.run_migrations:
            await run_in_threadpool(upgrade, db)
        if settings.start_worker:
            worker = Worker(ctx)
            app.state.worker = worker
            ctx.on_queued = worker.wake
            await run_in_threadpool(worker.start)
        if settings.freeze_startup_heap:
            # Move the start-up heap (framework, ORM, numpy: ~10^6 objects) out of the garbage
            # collector's reach: a full collection then scans only request garbage, instead of
            # adding ~50 ms to a profile read that allocates its rows (measured, see benchmarks).
            gc.collect()
            gc.freeze()
        try:
            yield
        finally:
            if settings.freeze_startup_heap:
                gc.unfreeze()
            if app.state.worker is not None:
                await run_in_threadpool(app.state.worker.stop)
                app.state.worker = None
            await run_in_threadpool(keys.flush)
            if releaser is not None:
                releaser.stop()
            db.dispose()

    app = FastAPI(
        title="TrackProfile",
        version=__version__,
        description=DESCRIPTION,
        lifespan=lifespan,
        docs_url=None,
        redoc_url=None,
        # A path with a trailing slash (or an encoded one: /vehicles/%2F) is 404, not an
        # undocumented 307 to another resource.
        redirect_slashes=False,
        generate_unique_id_function=operation_id,
    )
    app.state.ctx = ctx
    app.state.worker = None
    app.state.keys = keys
    install_error_handlers(app)
    app.include_router(health.router)
    app.include_router(api_router)
    install_web(app, settings)

    app.add_middleware(
        BodySizeLimitMiddleware,
        upload_limit_bytes=settings.max_upload_bytes,
        body_limit_bytes=settings.max_body_bytes,
        large_paths=UPLOAD_PATHS,
    )
    # Outside the size limit: an unauthorised client is refused before its body is looked at.
    app.add_middleware(AccessMiddleware, settings=settings, keys=keys)
    if settings.cors_origins:
        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origins,
            allow_methods=["GET", "POST", "DELETE"],
            allow_headers=["Content-Type", "X-API-Key", "Authorization", "Idempotency-Key"],
        )
    app.add_middleware(SecurityHeadersMiddleware)

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = get_openapi(
                title=app.title, version=app.version, description=app.description,
                routes=app.routes,
            )  # fmt: skip
            # The JSON upload bodies are documented by hand (the routes also take multipart),
            # so their schemas are added to the components here.
            add_body_models(schema, [RunCreateJson, SurveyCreateJson])
            security_as_configured(schema, settings)
            errors_as_json(schema)
            bounded_integers(schema)
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
    return app


app = create_app()
