"""Server-side chart views for the dashboard: decimated profiles, chainage maps, CSV previews.

The work is done by :mod:`app.services.views.charts`; these routes parse and serialise.

A dashboard must never receive millions of points: a 100 km run has 400 000 grid points and a
track may carry fifty of them. These endpoints answer what a chart of a given width can show:

- ``GET /views/runs/{id}/profile``: one run's profile in a window, min/max-decimated to
  ``max_points`` (a dip survives any decimation factor).
- ``GET /views/tracks/{track}/chainage-map``: every processed run of a track as a row of the
  chainage map, the soft spots of all of them (columnar), the zones they form across runs, and
  for windows up to ``HEATMAP_MAX_SPAN_M`` the lowest level per run and chainage bin, computed
  by the database (GROUP BY over a range scan of the profile's primary key).
- ``GET /views/tracks/{track}/window``: the fused profiles of all runs around one zone.
- ``POST /views/csv-preview``: the engine's reading of the head of a log (columns, first rows,
  recognised columns and units) for the upload page.

Chainage is served aligned (stored chainage + the run's ``chainage_offset_m``), levels in mm.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, File, Query, Request, UploadFile
from starlette.datastructures import UploadFile as StarletteUpload

from app.api.deps import ClosedWindowDep, RunId, SessionDep, WindowDep
from app.schemas.views import ChainageMapPublic, CsvPreviewPublic, ProfileViewPublic, WindowPublic
from app.services.errors import Invalid
from app.services.lookup import get_track
from app.services.views import charts as chart_views

router = APIRouter(prefix="/views", tags=["views"])

MaxRuns = Annotated[int, Query(ge=1, le=1000, description="Newest runs shown")]
"""``?max_runs=``: how many of the track's runs a view shows at most (the newest)."""


@router.get("/runs/{run_id}/profile", response_model=ProfileViewPublic)
def run_profile_view(
    session: SessionDep,
    run_id: RunId,
    window: WindowDep,
    max_points: Annotated[int, Query(ge=100, le=50_000, description="Most points")] = 4000,
) -> ProfileViewPublic:
    """A run's profile (fused, front, rear, baseline; mm) in a window, decimated for display."""
    return chart_views.run_profile_view(session, run_id, window, max_points)


@router.get("/tracks/{track}/chainage-map", response_model=ChainageMapPublic)
def track_chainage_map(
    session: SessionDep,
    track: str,
    window: WindowDep,
    bins: Annotated[int, Query(ge=10, le=5000, description="Heatmap bins across")] = 1200,
    spots: Annotated[bool, Query(description="Include the soft spots")] = True,
    zones: Annotated[bool, Query(description="Include the zones (needs spots)")] = True,
    heatmap: Annotated[bool, Query(description="Include the level heatmap")] = True,
    max_runs: MaxRuns = 200,
) -> ChainageMapPublic:
    """The chainage map of a track (its name or id): runs x chainage, soft spots, zones.

    Without a window the whole extent of the track's runs is served. The heatmap (lowest level
    per run and bin) is computed only for windows up to 10 km wide; zoom in for it.
    """
    return chart_views.chainage_map(
        session, get_track(session, track), window,
        bins=bins, spots=spots, zones=zones, heatmap=heatmap, max_runs=max_runs,
    )  # fmt: skip


@router.get("/tracks/{track}/window", response_model=WindowPublic)
def track_window(
    session: SessionDep,
    track: str,
    window: ClosedWindowDep,
    max_points: Annotated[int, Query(ge=100, le=20_000, description="Most points per run")] = 2000,
    max_runs: MaxRuns = 200,
) -> WindowPublic:
    """The fused profile of every processed run covering part of ``[from_m, to_m]``."""
    return chart_views.track_window(
        session, get_track(session, track), window, max_points=max_points, max_runs=max_runs
    )


@router.post("/csv-preview", response_model=CsvPreviewPublic)
async def csv_preview(
    request: Request,
    file: Annotated[UploadFile, File(description="The first bytes of a run log (CSV, gzip)")],
    n_rows: Annotated[int, Query(ge=1, le=100, description="Data rows returned")] = 10,
) -> CsvPreviewPublic:
    """How the engine would read a log: columns, first rows, recognised columns and units.

    Send the file (or its first bytes; at most 256 KB are read) and, optionally, the same
    column/unit form fields as the upload to see their effect. Nothing is stored. Problems of
    the content come back as ``warnings``; an empty or non-text file answers 422.
    """
    form = await request.form()
    if not isinstance(form.get("file"), StarletteUpload):  # a text field named "file"
        raise Invalid("'file' must be a file part (the log's first bytes)", field="file")
    unknown = sorted(set(form) - {"file", *chart_views.PREVIEW_OPTION_NAMES})
    if unknown:
        raise Invalid(f"unexpected form field {unknown[0][:50]!r}", field=unknown[0][:50])
    chosen = {
        k: str(v).strip()
        for k in chart_views.PREVIEW_OPTION_NAMES
        if isinstance(v := form.get(k), str) and v.strip() and v.strip() != "auto"
    }
    data = await file.read(chart_views.PREVIEW_MAX_BYTES)
    return chart_views.csv_preview(data, n_rows, chosen)
