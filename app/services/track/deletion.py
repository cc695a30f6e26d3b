"""How many runs tracks have; a track deleted with everything derived from it."""

from __future__ import annotations

from sqlalchemy import delete, func, select
from sqlalchemy.orm import Session

from app.db.models import Run, Track
from app.services.track.integrate import lock_track


def run_counts(session: Session, track_ids: list[int]) -> dict[int, int]:
    """How many runs each of the tracks ``track_ids`` has (tracks without runs left out)."""
    if not track_ids:
        return {}
    rows = session.execute(
        select(Run.track_id, func.count()).where(Run.track_id.in_(track_ids)).group_by(Run.track_id)
    ).all()
    return {int(t): int(n) for t, n in rows}


def delete_track(session: Session, track: Track) -> int:
    """Delete ``track``, its runs (profiles, soft spots, signals, logs) and its derived data
    (aggregate, register inputs, stiffness, limits, surveys). Returns how many runs went.

    The track is locked first (:func:`app.services.track.integrate.lock_track`), so a worker
    storing a run of this track finishes before the delete reads it, or finds its run gone
    afterwards and drops its result (the worker's store checks the run still exists). The
    rows that hang off runs and tracks go by the database's ``ON DELETE CASCADE``.
    """
    lock_track(session, track.id)
    n_runs = session.scalar(select(func.count()).where(Run.track_id == track.id)) or 0
    session.execute(delete(Run).where(Run.track_id == track.id))
    session.execute(delete(Track).where(Track.id == track.id))
    session.expunge(track)
    return int(n_runs)
