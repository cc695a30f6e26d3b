"""A track's centerline (issue 11): ``PUT/GET/DELETE /api/v1/tracks/{track}/centerline`` and its
plan view ``GET /api/v1/tracks/{track}/centerline/plan``. ``{track}`` is the id or name."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse

from app.api.deps import CtxDep, SessionDep
from app.api.uploads import content_type
from app.db.models import TrackCenterline
from app.schemas.centerlines import (
    CENTERLINE_CSV_SCHEMA,
    CENTERLINE_GEOJSON_SCHEMA,
    CenterlinePublic,
)
from app.services.context import AppContext
from app.services.errors import Invalid
from app.services.lookup import get_track
from app.services.track.centerlines import (
    CONTENT_TYPES,
    as_geojson,
    centerline_row,
    delete_centerline,
    plan_view,
    read_centerline,
    store_centerline,
)

router = APIRouter(prefix="/tracks", tags=["centerlines"])


def _public(row: TrackCenterline) -> CenterlinePublic:
    return CenterlinePublic(
        track_id=row.track_id, n_vertices=row.n_vertices, length_m=row.length_m,
        start_chainage_m=row.start_chainage_m, end_chainage_m=row.end_chainage_m,
        source=row.source, updated_at=row.updated_at,
    )  # fmt: skip


CENTERLINE_BODY_DOC: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "description": "A GeoJSON LineString in WGS84 [longitude, latitude] (bare, as a "
        "Feature or as a one-feature FeatureCollection; the chainage of its first vertex is "
        "the Feature property or query parameter start_chainage_m, default 0), or a CSV "
        "chainage_m,lat,lon with the chainage of every vertex. At most the body limit "
        "(TRACKPROFILE_MAX_BODY_KB).",
        "content": {
            "application/geo+json": {"schema": CENTERLINE_GEOJSON_SCHEMA},
            "application/json": {"schema": CENTERLINE_GEOJSON_SCHEMA},
            "text/csv": {"schema": CENTERLINE_CSV_SCHEMA},
        },
    }
}


def _store(
    ctx: AppContext, track: str, data: bytes, ctype: str, start: float | None
) -> tuple[CenterlinePublic, bool]:
    line, source = read_centerline(data, ctype, start)
    with ctx.db.session() as s:
        trk = get_track(s, track)
        row, created = store_centerline(s, trk, line, source)
        s.commit()
        return _public(row), created


@router.put(
    "/{track}/centerline",
    response_model=CenterlinePublic,
    openapi_extra=CENTERLINE_BODY_DOC,
    responses={201: {"model": CenterlinePublic, "description": "The track had no centerline"}},
)
async def put_centerline(
    request: Request,
    response: Response,
    ctx: CtxDep,
    track: str,
    start_chainage_m: Annotated[
        float | None,
        Query(
            description="Chainage of the first vertex of a GeoJSON line, m (default: the "
            "Feature's property start_chainage_m, else 0)",
            allow_inf_nan=False,
        ),
    ] = None,
) -> CenterlinePublic:
    """Store (or replace) the track's centerline. Runs uploaded afterwards with GNSS fixes and
    no start chainage are placed on it. A line with fewer than two distinct points, one that
    crosses itself, degrees out of range (naming a lat/lon swap when that is the cause) or a
    CSV chainage that does not grow is answered 422 naming the vertex or line; nothing is
    stored then."""
    ctype = content_type(request, CONTENT_TYPES, ", ".join(CONTENT_TYPES))
    data = await request.body()
    if not data.strip():
        raise Invalid("the centerline body is empty", field="body")
    public, created = await run_in_threadpool(_store, ctx, track, data, ctype, start_chainage_m)
    response.status_code = 201 if created else 200
    return public


@router.get(
    "/{track}/centerline",
    response_class=JSONResponse,
    responses={200: {"content": {"application/geo+json": {"schema": {"type": "object"}}}}},
)
def get_centerline(session: SessionDep, track: str) -> JSONResponse:
    """The track's centerline as a GeoJSON Feature (WGS84 lon/lat; the chainage of each vertex
    and the line's figures in ``properties``); 404 when the track has none."""
    row = centerline_row(session, get_track(session, track))
    return JSONResponse(as_geojson(row), media_type="application/geo+json")


@router.get("/{track}/centerline/summary", response_model=CenterlinePublic)
def get_centerline_summary(session: SessionDep, track: str) -> CenterlinePublic:
    """The centerline's figures without its vertices (404 when the track has none): cheap
    enough for a form to ask whether runs on this track can be placed by GNSS."""
    return _public(centerline_row(session, get_track(session, track)))


@router.get("/{track}/centerline/plan")
def get_centerline_plan(session: SessionDep, track: str) -> dict[str, Any]:
    """The line in local metres (``x_m`` east, ``y_m`` north of its centre) with the chainage of
    each vertex, for a plan view without map tiles; lon/lat too."""
    return plan_view(centerline_row(session, get_track(session, track)))


@router.delete("/{track}/centerline", status_code=204, response_class=Response)
def remove_centerline(session: SessionDep, track: str) -> Response:
    """Delete the track's centerline (runs placed by it keep their chainage)."""
    delete_centerline(session, get_track(session, track))
    session.commit()
    return Response(status_code=204)
