"""Track intelligence: a track's aggregated profile, defect register, alerts, limits, report.

``{track}`` is the track's id or its name. Chainage is aligned (each run's offset applied).
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime
from typing import Annotated, Any, Literal

import orjson
from fastapi import APIRouter, Query, Response
from fastapi.responses import HTMLResponse
from sqlalchemy.orm import Session

from app.api.answers import Format, add_csv_twin, csv_answer
from app.api.deps import CtxDep, SessionDep, WindowDep
from app.db.models import Track
from app.schemas.common import Timestamp
from app.schemas.track_intel import (
    DefectPublic,
    LimitsPublic,
    LimitsUpdate,
    TrackProfileAggregatePublic,
)
from app.services.lookup import get_track
from app.services.track.aggregate import aggregated_profile_view
from app.services.track.register import (
    LIMIT_FIELDS,
    load_limits,
    provisional_notes,
    save_limits,
    stiffness_notes,
    track_register,
)
from app.services.vehicles.versions import read_settled, require_settled
from app.services.views import exports
from app.services.views.report import REPORT_CSP
from engine.register import Defect, Limits

router = APIRouter(prefix="/tracks", tags=["track intelligence"])


@router.get(
    "/{track}/profile",
    response_model=TrackProfileAggregatePublic,
)
def read_aggregated_profile(
    ctx: CtxDep,
    session: SessionDep,
    track: str,
    window: WindowDep,
    max_points: Annotated[
        int | None,
        Query(ge=100, le=1_000_000, description="Thin to at most this many points (JSON)"),
    ] = None,
    format: Format = "json",
) -> Response:
    """The track's aggregated profile: per 0.25 m of aligned chainage, the median level of the
    aligned runs covering it (mm), their robust spread (mm) and how many they are.

    ``?from_m=&to_m=`` selects a window (inclusive; one indexed range scan); the ``.csv`` twin
    answers ``chainage_m,level_mm,spread_mm,n_runs``; ``?max_points=`` thins a JSON answer
    keeping each bucket's lowest and highest point.
    """
    trk = get_track(session, track)
    if format == "csv":
        require_settled(session, trk.id, "profile")
        csv = exports.track_profile_csv(ctx, trk.id, window)
        return csv_answer(csv, f"track-{trk.id}-profile.csv")
    payload = read_settled(
        session, trk.id, "profile",
        lambda: aggregated_profile_view(session, trk, window, max_points),
    )  # fmt: skip
    return Response(orjson.dumps(payload), media_type="application/json")


def _defects_answer(
    session: Session,
    track_id: int,
    defects: Sequence[Defect],
    fmt: str,
    with_history: bool,
    filename: str,
) -> Any:
    notes = stiffness_notes(session, track_id, defects)
    trust = provisional_notes(session, track_id, defects)
    if fmt == "csv":
        return csv_answer(exports.defects_csv(defects, notes, trust), filename)
    # The register's own dicts, serialised once (FastAPI's response-model pass would double
    # the time of a large register); their fields are those of DefectPublic.
    payload = [
        exports.defect_dict(d, with_history) | exports.note_dict(note) | tr.to_dict()
        for d, note, tr in zip(defects, notes, trust, strict=True)
    ]
    return Response(orjson.dumps(payload), media_type="application/json")


IncludeHistory = Annotated[
    Literal["history"] | None,
    Query(description="history: every run's sighting of each defect (JSON only)"),
]


@router.get("/{track}/defects", response_model=list[DefectPublic])
def read_defects(
    session: SessionDep,
    track: str,
    include: IncludeHistory = None,
    format: Format = "json",
) -> Any:
    """The soft-spot register: the soft spots of the track's aligned runs merged into tracked
    defects, with extent, first and last seen, runs seen (of the runs covering it), latest
    depth and stiffness loss, their trends per month, status and priority from the track's
    limits; most urgent first (priority, then depth). A defect the separation found is
    ``provisional`` (``provisional_reason`` names the vehicles and runs) while a vehicle behind
    it has neither a calibration applied nor its runs' loads declared."""
    trk = get_track(session, track)
    defects = read_settled(session, trk.id, "register", lambda: track_register(session, trk.id))
    return _defects_answer(
        session, trk.id, defects, format, include == "history", f"track-{trk.id}-defects.csv"
    )


@router.get("/{track}/alerts", response_model=list[DefectPublic])
def read_alerts(
    session: SessionDep,
    track: str,
    since: Annotated[
        Timestamp,
        Query(description="ISO 8601 date or time (UTC when no offset is given)"),
    ],
    include: IncludeHistory = None,
    format: Format = "json",
) -> Any:
    """Defects whose current limit level was reached at or after ``since`` (by the recording
    time of the first run at that level): what a maintenance planner pulls every morning.
    Most urgent first."""
    when = since if since.tzinfo is not None else since.replace(tzinfo=UTC)
    trk = get_track(session, track)
    defects = [
        d
        for d in read_settled(session, trk.id, "register", lambda: track_register(session, trk.id))
        if d.level is not None and d.level_since is not None and d.level_since >= when
    ]
    return _defects_answer(
        session, trk.id, defects, format, include == "history", f"track-{trk.id}-alerts.csv"
    )


def _limits_public(trk: Track, limits: Limits, updated_at: datetime | None) -> LimitsPublic:
    return LimitsPublic(
        track_id=trk.id,
        track=trk.name,
        is_default=updated_at is None,
        updated_at=updated_at,
        **limits.to_dict(),
    )


@router.get("/{track}/limits", response_model=LimitsPublic)
def read_limits(session: SessionDep, track: str) -> LimitsPublic:
    """The track's limits on defect depth (mm) and stiffness loss (%), or the defaults."""
    trk = get_track(session, track)
    limits, row = load_limits(session, trk.id)
    return _limits_public(trk, limits, row.updated_at if row is not None else None)


@router.put("/{track}/limits", response_model=LimitsPublic)
def update_limits(session: SessionDep, track: str, body: LimitsUpdate) -> LimitsPublic:
    """Set the track's limits (fields left out take their default; null switches a criterion
    off). Answers 422 naming the field when a value is not > 0 or the levels do not grow from
    alert to intervention to immediate."""
    trk = get_track(session, track)
    limits = Limits(**{k: getattr(body, k) for k in LIMIT_FIELDS})  # checks values and order
    row = save_limits(session, trk.id, limits)
    session.commit()
    return _limits_public(trk, limits, row.updated_at)


@router.get(
    "/{track}/report",
    response_class=HTMLResponse,
    responses={200: {"content": {"text/html": {"schema": {"type": "string"}}}}},
)
def read_report(
    session: SessionDep,
    track: str,
    top: Annotated[int, Query(ge=1, le=1000, description="Defects listed")] = 25,
    download: Annotated[bool, Query(description="Answer as an attachment")] = False,
) -> HTMLResponse:
    """A self-contained HTML report of the track: chainage map (inline SVG) of the aggregated
    profile and the defects, the top defects, the limits and the runs. No scripts, no
    external resources: it can be saved, mailed or printed as it is."""
    trk = get_track(session, track)
    html = read_settled(session, trk.id, "report", lambda: exports.track_report(session, trk, top))
    disposition = "attachment" if download else "inline"
    return HTMLResponse(
        html,
        headers={
            "Content-Security-Policy": REPORT_CSP,
            "Content-Disposition": f'{disposition}; filename="track-{trk.id}-report.html"',
        },
    )


add_csv_twin(router, "/{track}/profile", read_aggregated_profile)
add_csv_twin(router, "/{track}/defects", read_defects)
add_csv_twin(router, "/{track}/alerts", read_alerts)
