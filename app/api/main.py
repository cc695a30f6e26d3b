"""The ``/api/v1`` router: every resource router, behind the access check."""

from __future__ import annotations

from fastapi import APIRouter, Depends

from app.api.deps import check_access
from app.api.routes import (
    centerlines,
    quality,
    runs,
    simulate,
    stiffness,
    track_intel,
    tracks,
    vehicles,
    views,
)
from app.schemas.common import ERROR_RESPONSES

UPLOAD_PATHS = frozenset({"/api/v1/runs"})
"""Routes whose body may be as large as the upload limit (every other body is small)."""

api_router = APIRouter(
    prefix="/api/v1", dependencies=[Depends(check_access)], responses=ERROR_RESPONSES
)
api_router.include_router(runs.router)
api_router.include_router(tracks.router)
# Per-track aggregated profile, defect register, alerts, limits and report.
api_router.include_router(track_intel.router)
# Geometry vs stiffness: separated stiffness and reference surveys of a track.
api_router.include_router(stiffness.router)
# Positions from GNSS: a track's centerline.
api_router.include_router(centerlines.router)
# Track quality in EN 13848 terms: D1/D2 sections, isolated defects, line speeds, GeoJSON.
api_router.include_router(quality.router)
api_router.include_router(vehicles.router)
api_router.include_router(simulate.router)
# Server-side chart data for the dashboard (decimated profiles, chainage maps, CSV preview).
api_router.include_router(views.router)
