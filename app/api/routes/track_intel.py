"""Track intelligence: a track's aggregated profile, defect register, alerts, limits, report.

``{track}`` is the track's id or its name. Chainage is aligned (each run's offset applied).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from datetime import UTC, datetime
from typing import Annotated, Any, Literal

import numpy as np
import orjson
from fastapi import APIRouter, Query, Response
from fastapi.responses import HTMLResponse, StreamingResponse
from sqlalchemy import func, select

from app.api.deps import CtxDep, SessionDep
from app.core.errors import ApiError
from app.db.models import Run, Track
from app.schemas.track_intel import (
    DefectPublic,
    LimitsPublic,
    LimitsUpdate,
    TrackProfileAggregatePublic,
)
from app.services.aggregate import read_track_profile
from app.services.context import AppContext
from app.services.register import LIMIT_FIELDS, load_limits, save_limits, track_register
from app.services.report import REPORT_CSP, ReportInput, ReportRun, render_report
from engine.chainage import GRID_STEP_M
from engine.decimate import minmax_indices
from engine.register import Defect, Limits

from .lookup import get_track

router = APIRouter(prefix="/tracks", tags=["track intelligence"])

CSV_RESPONSE: dict[int | str, dict[str, Any]] = {
    200: {"content": {"text/csv": {"schema": {"type": "string"}}}}
}
DEFECT_CSV_FIELDS = (
    "priority", "id", "level", "level_since", "status", "start_m", "end_m", "peak_m",
    "depth_mm", "stiffness_loss_pct", "trend_mm_per_month", "trend_loss_pct_per_month",
    "runs_seen", "runs_covering", "first_seen", "last_seen",
)  # fmt: skip
REPORT_RUNS = 200
"""Runs listed in the report (the newest)."""


def _check_window(from_m: float | None, to_m: float | None) -> None:
    if from_m is not None and to_m is not None and to_m < from_m:
        raise ApiError(422, f"to_m ({to_m} m) is before from_m ({from_m} m)", field="to_m")


@router.get(
    "/{track}/profile",
    response_model=TrackProfileAggregatePublic,
    responses=CSV_RESPONSE,
)
def read_aggregated_profile(
    ctx: CtxDep,
    session: SessionDep,
    track: str,
    from_m: Annotated[float | None, Query(allow_inf_nan=False, description="From, m")] = None,
    to_m: Annotated[float | None, Query(allow_inf_nan=False, description="To, m")] = None,
    max_points: Annotated[
        int | None,
        Query(ge=100, le=1_000_000, description="Thin to at most this many points (JSON)"),
    ] = None,
    format: Annotated[Literal["json", "csv"], Query()] = "json",
) -> Response:
    """The track's aggregated profile: per 0.25 m of aligned chainage, the median level of the
    aligned runs covering it (mm), their robust spread (mm) and how many they are.

    ``?from_m=&to_m=`` selects a window (inclusive; one indexed range scan); ``?format=csv``
    answers ``chainage_m,level_mm,spread_mm,n_runs``; ``?max_points=`` thins a JSON answer
    keeping each bucket's lowest and highest point.
    """
    _check_window(from_m, to_m)
    trk = get_track(session, track)
    if format == "csv":
        return StreamingResponse(
            _profile_csv(ctx, trk.id, from_m, to_m),
            media_type="text/csv",
            headers={"Content-Disposition": f'attachment; filename="track-{trk.id}-profile.csv"'},
        )
    cols = read_track_profile(session, trk.id, from_m, to_m)
    n = len(cols["chainage_m"])
    decimated = False
    if max_points is not None and n > max_points:
        idx = minmax_indices(np.asarray(cols["level_mm"], dtype=np.float64), max_points)
        cols = {k: [v[i] for i in idx.tolist()] for k, v in cols.items()}
        decimated = True
    payload = {
        "track_id": trk.id,
        "track": trk.name,
        "from_m": from_m,
        "to_m": to_m,
        "grid_step_m": GRID_STEP_M,
        "n": n,
        "decimated": decimated,
        **cols,
    }
    return Response(orjson.dumps(payload), media_type="application/json")


def _profile_csv(
    ctx: AppContext, track_id: int, from_m: float | None, to_m: float | None
) -> Iterator[str]:
    yield "chainage_m,level_mm,spread_mm,n_runs\n"
    with ctx.db.session() as s:
        cols = read_track_profile(s, track_id, from_m, to_m)
    rows = zip(cols["chainage_m"], cols["level_mm"], cols["spread_mm"], cols["n_runs"], strict=True)
    batch: list[str] = []
    for c, lv, sp, n in rows:
        batch.append(f"{c:.2f},{lv:.6f},{sp:.6f},{n}\n")
        if len(batch) >= 20_000:
            yield "".join(batch)
            batch = []
    yield "".join(batch)


def _iso(v: object) -> str:
    return "" if v is None else str(v)


def _defects_answer(defects: Sequence[Defect], fmt: str, with_history: bool, filename: str) -> Any:
    if fmt == "csv":
        lines = [",".join(DEFECT_CSV_FIELDS)]
        for d in defects:
            row = defect_dict(d)
            cells = []
            for k in DEFECT_CSV_FIELDS:
                v = row[k]
                if isinstance(v, float):
                    cells.append(f"{v:.6g}" if math.isfinite(v) else "")
                else:
                    cells.append(_iso(v))
            lines.append(",".join(cells))
        return Response(
            "\n".join(lines) + "\n",
            media_type="text/csv",
            headers={"Content-Disposition": f'attachment; filename="{filename}"'},
        )
    # The register's own dicts, serialised once (FastAPI's response-model pass would double
    # the time of a large register); their fields are those of DefectPublic.
    payload = [defect_dict(d, with_history) for d in defects]
    return Response(orjson.dumps(payload), media_type="application/json")


DEFECT_FIELDS = tuple(f.name for f in dataclasses.fields(Defect) if f.name != "history")


def defect_dict(d: Defect, with_history: bool = False) -> dict[str, Any]:
    """A defect as JSON-ready values (``Defect.to_dict`` without deep-copying the history
    unless it is asked for: a large register answers in half the time)."""
    if with_history:
        return d.to_dict(with_history=True)
    out = {k: getattr(d, k) for k in DEFECT_FIELDS}
    for k in ("first_seen", "last_seen", "level_since"):
        if out[k] is not None:
            out[k] = out[k].isoformat()
    return out


IncludeHistory = Annotated[
    Literal["history"] | None,
    Query(description="history: every run's sighting of each defect (JSON only)"),
]


@router.get("/{track}/defects", response_model=list[DefectPublic], responses=CSV_RESPONSE)
def read_defects(
    session: SessionDep,
    track: str,
    include: IncludeHistory = None,
    format: Annotated[Literal["json", "csv"], Query()] = "json",
) -> Any:
    """The soft-spot register: the soft spots of the track's aligned runs merged into tracked
    defects, with extent, first and last seen, runs seen (of the runs covering it), latest
    depth and stiffness loss, their trends per month, status and priority from the track's
    limits; most urgent first (priority, then depth)."""
    trk = get_track(session, track)
    defects = track_register(session, trk.id)
    return _defects_answer(defects, format, include == "history", f"track-{trk.id}-defects.csv")


@router.get("/{track}/alerts", response_model=list[DefectPublic], responses=CSV_RESPONSE)
def read_alerts(
    session: SessionDep,
    track: str,
    since: Annotated[
        datetime,
        Query(description="ISO 8601 date or time (UTC when no offset is given)"),
    ],
    include: IncludeHistory = None,
    format: Annotated[Literal["json", "csv"], Query()] = "json",
) -> Any:
    """Defects whose current limit level was reached at or after ``since`` (by the recording
    time of the first run at that level): what a maintenance planner pulls every morning.
    Most urgent first."""
    when = since if since.tzinfo is not None else since.replace(tzinfo=UTC)
    trk = get_track(session, track)
    defects = [
        d
        for d in track_register(session, trk.id)
        if d.level is not None and d.level_since is not None and d.level_since >= when
    ]
    return _defects_answer(defects, format, include == "history", f"track-{trk.id}-alerts.csv")


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
    limits, limits_row = load_limits(session, trk.id)
    defects = track_register(session, trk.id, limits)
    cols = read_track_profile(session, trk.id)
    count = select(func.count()).select_from(Run).where(Run.track_id == trk.id)
    runs_total = session.scalar(count) or 0
    runs = session.scalars(
        select(Run)
        .where(Run.track_id == trk.id)
        .order_by(func.coalesce(Run.recorded_at, Run.created_at).desc(), Run.id.desc())
        .limit(REPORT_RUNS)
    ).all()
    report_runs = [
        ReportRun(
            id=r.id,
            name=r.name,
            recorded_at=r.recorded_at,
            vehicle=r.vehicle.name,
            filename=r.original_filename,
            status=r.status,
            alignment_status=r.alignment_status,
            offset_m=r.chainage_offset_m or 0.0,
            correlation=r.alignment_correlation,
            n_soft_spots=r.n_soft_spots,
            chainage_min_m=None
            if r.chainage_min_m is None
            else r.chainage_min_m + (r.chainage_offset_m or 0.0),
            chainage_max_m=None
            if r.chainage_max_m is None
            else r.chainage_max_m + (r.chainage_offset_m or 0.0),
        )  # fmt: skip
        for r in runs
    ]
    html = render_report(
        ReportInput(
            track_name=trk.name,
            track_id=trk.id,
            description=trk.description,
            generated_at=datetime.now(UTC),
            defects=defects,
            limits=limits,
            limits_are_default=limits_row is None,
            runs=report_runs,
            runs_total=int(runs_total),
            chainage_m=np.asarray(cols["chainage_m"], dtype=np.float64),
            level_mm=np.asarray(cols["level_mm"], dtype=np.float64),
            spread_mm=np.asarray(cols["spread_mm"], dtype=np.float64),
            top=top,
        )
    )
    disposition = "attachment" if download else "inline"
    return HTMLResponse(
        html,
        headers={
            "Content-Security-Policy": REPORT_CSP,
            "Content-Disposition": f'{disposition}; filename="track-{trk.id}-report.html"',
        },
    )
