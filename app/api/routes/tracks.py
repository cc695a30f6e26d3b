"""Tracks: ``GET/POST /api/v1/tracks``, ``GET/DELETE /api/v1/tracks/{track}`` (id or name)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError

from app.api.convert import track_public
from app.api.deps import SessionDep
from app.db.models import Run, Track
from app.schemas.tracks import TrackCreate, TrackPublic, TracksPublic
from app.services.errors import Conflict
from app.services.tracks import delete_track as delete_track_and_runs
from engine.track import TrackParams

from .lookup import get_track

router = APIRouter(prefix="/tracks", tags=["tracks"])


def _run_counts(session: SessionDep, ids: list[int]) -> dict[int, int]:
    if not ids:
        return {}
    rows = session.execute(
        select(Run.track_id, func.count()).where(Run.track_id.in_(ids)).group_by(Run.track_id)
    ).all()
    return {int(t): int(n) for t, n in rows}


@router.get("", response_model=TracksPublic)
def list_tracks(
    session: SessionDep,
    offset: Annotated[int, Query(ge=0)] = 0,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
) -> TracksPublic:
    """Tracks by name, with how many runs each has."""
    count = session.scalar(select(func.count()).select_from(Track)) or 0
    tracks = session.scalars(select(Track).order_by(Track.name).offset(offset).limit(limit)).all()
    counts = _run_counts(session, [t.id for t in tracks])
    return TracksPublic(data=[track_public(t, counts.get(t.id, 0)) for t in tracks], count=count)


@router.post("", response_model=TrackPublic, status_code=201)
def create_track(session: SessionDep, body: TrackCreate) -> TrackPublic:
    """Create a track; 409 if the name is taken."""
    params = body.model_dump(include=set(TrackParams.__dataclass_fields__))
    TrackParams.from_dict(params)  # the engine's checks (a ParameterError names the field)
    if session.scalar(select(Track.id).where(Track.name == body.name)) is not None:
        raise Conflict(f"a track named {body.name!r} already exists", field="name")
    track = Track(name=body.name, description=body.description, rail=body.rail, **params)
    session.add(track)
    try:
        session.commit()
    except IntegrityError:
        session.rollback()
        raise Conflict(f"a track named {body.name!r} already exists", field="name") from None
    return track_public(track, 0)


@router.get("/{track}", response_model=TrackPublic)
def read_track(session: SessionDep, track: str) -> TrackPublic:
    """One track, by id or name."""
    row = get_track(session, track)
    return track_public(row, _run_counts(session, [row.id]).get(row.id, 0))


@router.delete("/{track}", status_code=204, response_class=Response)
def delete_track(session: SessionDep, track: str) -> Response:
    """Delete a track (by id or name) with all its runs and everything derived from them:
    profiles, soft spots, aggregate, register, stiffness, limits and surveys."""
    delete_track_and_runs(session, get_track(session, track))
    session.commit()
    return Response(status_code=204)
