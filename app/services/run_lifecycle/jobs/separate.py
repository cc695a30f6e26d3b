"""Redoing a track's geometry/stiffness separation that a stored run left waiting."""

from __future__ import annotations

import logging
import time

from app.services.run_lifecycle.jobs.base import Crew, Job
from app.services.track.integrate import separate_pending, tracks_pending_separation

log = logging.getLogger(__name__)

SEPARATION_RETRY_S = 60.0
"""A track whose waiting separation failed is tried again after this long, s."""


class SeparateJob(Job):
    """Separates the tracks whose separation waits: right after the worker stored a run of
    the track (:meth:`separate_track`), else at an idle look (left by a process that stopped
    between a run's commit and its separation)."""

    def __init__(self, crew: Crew) -> None:
        super().__init__(crew)
        self._failed: dict[int, float] = {}  # track id: time.monotonic() of its failure

    def separate_track(self, track_id: int) -> bool:
        """Redo the separation a stored run left waiting on track ``track_id`` (one
        transaction, :func:`~app.services.track.integrate.separate_pending`); False when none was
        waiting or it failed (logged; the mark stays, retried at a later idle look)."""
        try:
            with self.ctx.db.session() as s:
                done = separate_pending(s, track_id)
                s.commit()
        except Exception:
            log.exception("separation of track %s failed", track_id)
            self._failed[track_id] = time.monotonic()
            return False
        self._failed.pop(track_id, None)
        return done

    def look(self) -> bool:
        """Redo one track's waiting separation; False when none waits. A track whose
        separation failed is retried after ``SEPARATION_RETRY_S``."""
        with self.ctx.db.session() as s:
            waiting = tracks_pending_separation(s)
        now = time.monotonic()
        for track_id in waiting:
            failed_at = self._failed.get(track_id)
            if failed_at is None or now - failed_at > SEPARATION_RETRY_S:
                return self.separate_track(track_id)
        return False
