"""Liveness and readiness: ``GET /healthz``."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from app import __version__
from app.api.deps import CtxDep
from app.schemas.status import HealthPublic
from app.services.status import database_status

router = APIRouter(tags=["health"])


@router.get("/healthz", response_model=HealthPublic, responses={503: {"model": HealthPublic}})
def healthz(request: Request, ctx: CtxDep) -> HealthPublic | JSONResponse:
    """200 when the database answers (and the worker runs), 503 otherwise.

    ``runs_processing`` is null when reads need an API key (the count is data)."""
    # The count is data: hidden when reads need a key (health itself stays open).
    answers, processing = database_status(
        ctx, count_processing=not ctx.settings.require_api_key_for_reads
    )
    database: Literal["ok", "error"] = "ok" if answers else "error"
    if not ctx.settings.start_worker:
        worker: Literal["running", "stopped", "disabled"] = "disabled"
    else:
        running = request.app.state.worker
        worker = "running" if running is not None and running.alive else "stopped"
    status: Literal["ok", "degraded", "error"] = (
        "error" if database == "error" else ("degraded" if worker == "stopped" else "ok")
    )
    body = HealthPublic(
        status=status, version=__version__, database=database, worker=worker,
        runs_processing=processing,
    )  # fmt: skip
    if status == "error":
        return JSONResponse(status_code=503, content=body.model_dump())
    return body
