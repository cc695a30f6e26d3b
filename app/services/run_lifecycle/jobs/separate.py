"""Redoing a track's geometry/stiffness separation that a stored run left waiting."""

from __future__ import annotations

from app.services.run_lifecycle.jobs.base import Crew, Job, Retries
from app.services.track.integrate import separate_pending, tracks_pending_separation

SEPARATION_RETRY_S = 60.0
"""A track whose waiting separation failed is tried again after this long, s."""


class SeparateJob(Job):
    """Separates the tracks whose separation waits: right after the worker stored a run of
    the track (:meth:`separate_track`), else at an idle look (left by a process that stopped
    between a run's commit and its separation)."""

    def __init__(self, crew: Crew) -> None:
        super().__init__(crew)
        self._retries = Retries(SEPARATION_RETRY_S)

    def separate_track(self, track_id: int) -> bool:
        """Redo the separation a stored run left waiting on track ``track_id`` (one
        transaction, :func:`~app.services.track.integrate.separate_pending`); False when none was
        waiting or it failed (logged; the mark stays, retried at a later idle look)."""

        def work() -> bool:
            with self.ctx.db.session() as s:
                done = separate_pending(s, track_id)
                s.commit()
            return done

        return self._retries.attempt(track_id, f"separation of track {track_id}", work)

    def look(self) -> bool:
        """Redo one track's waiting separation; False when none waits. A track whose
        separation failed is retried after ``SEPARATION_RETRY_S``."""
        with self.ctx.db.session() as s:
            waiting = tracks_pending_separation(s)
        for track_id in waiting:
            if self._retries.due(track_id):
                return self.separate_track(track_id)
        return False
