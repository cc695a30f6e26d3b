"""Track quality in EN 13848 terms: ``GET /tracks/{track}/quality`` (JSON, ``.csv``,
``.geojson``), ``GET/PUT /tracks/{track}/line-speeds``, ``GET/PUT /tracks/{track}/quality-limits``.
``{track}`` is the track's id or name; chainage is aligned."""

from __future__ import annotations

from typing import Annotated, Any

import orjson
from fastapi import APIRouter, Query, Response

from app.api.answers import Format, add_csv_twin, csv_answer
from app.api.deps import SessionDep, WindowDep
from app.schemas.quality import (
    LineSpeedRange,
    LineSpeedsBody,
    LineSpeedsPublic,
    QualityLimitsBody,
    QualityLimitsPublic,
    QualityPublic,
)
from app.services.lookup import get_track
from app.services.track import quality as svc
from app.services.views import quality_exports
from engine.quality_limits import SPEED_CLASSES_KMH, QualityLimits

router = APIRouter(prefix="/tracks", tags=["track quality"])

SectionM = Annotated[
    float, Query(ge=10.0, le=10_000.0, description="Section length, m (EN 13848-6: 200 m)")
]
Traces = Annotated[bool, Query(description="Add the D1/D2 levels every 1 m (JSON)")]


@router.get("/{track}/quality", response_model=QualityPublic)
def read_quality(
    session: SessionDep,
    track: str,
    window: WindowDep,
    section_m: SectionM = 200.0,
    traces: Traces = False,
    format: Format = "json",
) -> Response:
    """Longitudinal level per EN 13848: SD of D1 (3-25 m) and D2 per section with the number
    of passes, days since the last, repeatability, line speed and quality class; isolated
    defects (mean to peak) against the speed-class limits with the predicted date of the next
    limit; the comparison with the track's surveys. ``?from_m=&to_m=`` keeps the sections
    overlapping the window and the defects peaking in it (filtered with context, so their
    figures are the whole track's). The ``.csv`` twin answers the sections, then the defects."""
    trk = get_track(session, track)
    answer = svc.track_quality(
        session, trk, section_m, window=window, traces=traces and format == "json"
    )
    if format == "csv":
        return csv_answer(quality_exports.quality_csv(answer), f"track-{trk.id}-quality.csv")
    return Response(orjson.dumps(answer), media_type="application/json")


@router.get(
    "/{track}/quality.geojson",
    responses={200: {"content": {"application/geo+json": {"schema": {"type": "object"}}}}},
)
def read_quality_geojson(
    session: SessionDep, track: str, window: WindowDep, section_m: SectionM = 200.0
) -> Response:
    """The sections (LineString) and isolated defects (Point) placed on the track's
    centerline: a GeoJSON FeatureCollection in WGS84 (``[lon, lat]``) that QGIS opens."""
    trk = get_track(session, track)
    body = quality_exports.quality_geojson(session, trk, section_m, window)
    return Response(
        orjson.dumps(body),
        media_type="application/geo+json",
        headers={"Content-Disposition": f'attachment; filename="track-{trk.id}-quality.geojson"'},
    )


def _speeds_public(trk: Any, speeds: Any) -> LineSpeedsPublic:
    return LineSpeedsPublic(
        track_id=trk.id,
        track=trk.name,
        ranges=[
            LineSpeedRange(from_m=s.from_m, to_m=s.to_m, speed_kmh=s.speed_kmh) for s in speeds
        ],
    )


@router.get("/{track}/line-speeds", response_model=LineSpeedsPublic)
def read_line_speeds(session: SessionDep, track: str) -> LineSpeedsPublic:
    """The track's line speeds by chainage (km/h): they pick each place's speed class."""
    trk = get_track(session, track)
    return _speeds_public(trk, svc.load_line_speeds(session, trk.id))


@router.put("/{track}/line-speeds", response_model=LineSpeedsPublic)
def update_line_speeds(session: SessionDep, track: str, body: LineSpeedsBody) -> LineSpeedsPublic:
    """Replace the track's line speeds. 422 names a range whose end is not after its start,
    a speed outside 0-300 km/h, or two ranges that overlap."""
    trk = get_track(session, track)
    speeds = svc.save_line_speeds(
        session, trk.id, [(r.from_m, r.to_m, r.speed_kmh) for r in body.ranges]
    )
    session.commit()
    return _speeds_public(trk, speeds)


def _limits_public(trk: Any, limits: QualityLimits, is_default: bool) -> QualityLimitsPublic:
    d = limits.to_dict()
    return QualityLimitsPublic(
        track_id=trk.id,
        track=trk.name,
        is_default=is_default,
        speed_classes_kmh=list(SPEED_CLASSES_KMH),
        isolated_mm=d["isolated_mm"],  # type: ignore[arg-type]
        class_sd_mm=d["class_sd_mm"],  # type: ignore[arg-type]
    )


@router.get("/{track}/quality-limits", response_model=QualityLimitsPublic)
def read_quality_limits(session: SessionDep, track: str) -> QualityLimitsPublic:
    """The track's isolated-defect limits and quality-class bounds by speed class (or the
    defaults, docs/method.md)."""
    trk = get_track(session, track)
    limits, updated = svc.load_quality_limits(session, trk.id)
    return _limits_public(trk, limits, updated is None)


@router.put("/{track}/quality-limits", response_model=QualityLimitsPublic)
def update_quality_limits(
    session: SessionDep, track: str, body: QualityLimitsBody
) -> QualityLimitsPublic:
    """Set the track's quality limits (a key left out takes its default). 422 names a limit
    that is not > 0, limits that do not grow from alert to immediate, or class bounds that
    do not ascend."""
    trk = get_track(session, track)
    limits = svc.save_quality_limits(session, trk.id, body.model_dump(exclude_none=True))
    session.commit()
    return _limits_public(trk, limits, False)


add_csv_twin(router, "/{track}/quality", read_quality)
