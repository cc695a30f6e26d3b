"""The ``/api/v1`` router: every resource router, behind the access check."""

from __future__ import annotations

import importlib
import importlib.util

from fastapi import APIRouter, Depends

from app.api.deps import check_access
from app.api.routes import runs, simulate, tracks, vehicles
from app.schemas.common import ERROR_RESPONSES

VIEWS_MODULE = "app.api.routes.views"
"""Optional router of server-side chart views (decimated/aggregated data for the dashboard);
included when the module exists."""

api_router = APIRouter(
    prefix="/api/v1", dependencies=[Depends(check_access)], responses=ERROR_RESPONSES
)
api_router.include_router(runs.router)
api_router.include_router(tracks.router)
api_router.include_router(vehicles.router)
api_router.include_router(simulate.router)
if importlib.util.find_spec(VIEWS_MODULE) is not None:
    api_router.include_router(importlib.import_module(VIEWS_MODULE).router)
