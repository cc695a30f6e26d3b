"""Tracks: ``GET/POST /api/v1/tracks``, ``GET/DELETE /api/v1/tracks/{track}`` (id or name)."""

from __future__ import annotations

from fastapi import APIRouter, Response

from app.api.convert import track_public
from app.api.deps import PageDep, SessionDep
from app.schemas.tracks import TrackCreate, TrackPublic, TracksPublic
from app.services import lookup
from app.services.track.centerlines import with_centerline
from app.services.track.deletion import delete_track as delete_track_and_runs
from app.services.track.deletion import run_counts

router = APIRouter(prefix="/tracks", tags=["tracks"])


@router.get("", response_model=TracksPublic)
def list_tracks(session: SessionDep, page: PageDep) -> TracksPublic:
    """Tracks by name, with how many runs each has."""
    tracks, count = lookup.list_tracks(session, page.offset, page.limit)
    ids = [t.id for t in tracks]
    counts, lines = run_counts(session, ids), with_centerline(session, ids)
    return TracksPublic(
        data=[track_public(t, counts.get(t.id, 0), t.id in lines) for t in tracks], count=count
    )


@router.post("", response_model=TrackPublic, status_code=201)
def create_track(session: SessionDep, body: TrackCreate) -> TrackPublic:
    """Create a track; 409 if the name is taken."""
    track = lookup.create_track(session, body.name, body.model_dump(exclude={"name"}))
    return track_public(track, 0)


@router.get("/{track}", response_model=TrackPublic)
def read_track(session: SessionDep, track: str) -> TrackPublic:
    """One track, by id or name."""
    row = lookup.get_track(session, track)
    n_runs = run_counts(session, [row.id]).get(row.id, 0)
    return track_public(row, n_runs, row.id in with_centerline(session, [row.id]))


@router.delete("/{track}", status_code=204, response_class=Response)
def delete_track(session: SessionDep, track: str) -> Response:
    """Delete a track (by id or name) with all its runs and everything derived from them:
    profiles, soft spots, aggregate, register, stiffness, limits and surveys."""
    delete_track_and_runs(session, lookup.get_track(session, track))
    session.commit()
    return Response(status_code=204)
