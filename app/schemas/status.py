"""The service's own status: ``GET /healthz``."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel


class HealthPublic(BaseModel):
    """Service health."""

    status: Literal["ok", "degraded", "error"]
    version: str
    database: Literal["ok", "error"]
    worker: Literal["running", "stopped", "disabled"]
    runs_processing: int | None
