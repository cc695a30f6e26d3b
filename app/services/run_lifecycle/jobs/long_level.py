"""Storing the long level of a run answered done without it (``Run.long_level_pending``)."""

from __future__ import annotations

import logging
from datetime import datetime, timedelta

import numpy as np
from sqlalchemy import select

from app.db.base import utcnow
from app.db.models import Run, RunInput
from app.services.run_lifecycle.inversion import ClaimedRun
from app.services.run_lifecycle.jobs.base import Crew, Job, Retries
from app.services.track.integrate import runs_pending_long_level, store_long_level
from engine.setup import PreparedRun
from engine.track_quality import long_level

log = logging.getLogger(__name__)

LONG_LEVEL_GRACE_S = 60.0
"""A done run's long level is left to the worker that stored the run for this long (it
inverts it right after the commit) before any worker's idle look inverts it again from the
stored log, s."""

LONG_LEVEL_RETRY_S = 60.0
"""A run whose long level failed is tried again after this long, s."""


class LongLevelJob(Job):
    """Inverts and stores the long level D2 is filtered from (:func:`engine.track_quality.
    long_level`) of a run the worker answered done without it: right after storing the run
    (:meth:`complete`, from the log still in memory), else at an idle look (left by a process
    that stopped in between: from the stored log)."""

    def __init__(self, crew: Crew) -> None:
        super().__init__(crew)
        self._retries = Retries(LONG_LEVEL_RETRY_S)

    def complete(self, run_id: int, processed_at: datetime | None, run: PreparedRun) -> bool:
        """Invert ``run``'s long level under a processing slot and store it as the long level
        of run ``run_id`` as processed at ``processed_at`` (one transaction,
        :func:`~app.services.track.integrate.store_long_level`); False when the run changed
        meanwhile or it failed (logged; the mark stays, retried at a later idle look)."""

        def work() -> bool:
            with self.ctx.slots:
                long = long_level(run)
            with self.ctx.db.session() as s:
                done = store_long_level(s, run_id, processed_at, run.grid, long)
                s.commit()
            return done

        return self._retries.attempt(run_id, f"long level of run {run_id}", work)

    def look(self) -> bool:
        """Store one waiting long level older than ``LONG_LEVEL_GRACE_S``; False when none
        waits. A run whose stored log is gone, or whose vehicle changed since (it is
        processed again), has its mark cleared without one: its D2 says so."""
        with self.ctx.db.session() as s:
            waiting = runs_pending_long_level(s, utcnow() - timedelta(seconds=LONG_LEVEL_GRACE_S))
        for run_id, processed_at in waiting:
            if not self._retries.due(run_id):
                continue
            run = self._stored(run_id)
            if run is None:
                with self.ctx.db.session() as s:
                    store_long_level(s, run_id, processed_at, np.empty(0), None)
                    s.commit()
                return True
            return self.complete(run_id, processed_at, run)
        return False

    def _stored(self, run_id: int) -> PreparedRun | None:
        """Run ``run_id`` prepared from its stored log as it was processed; None when its log
        is gone or its vehicle changed since."""
        with self.ctx.db.session() as s:
            run = s.get(Run, run_id)
            packed = s.scalar(select(RunInput.data).where(RunInput.run_id == run_id))
            if run is None or packed is None or run.vehicle_version != run.vehicle.version:
                return None
            claimed = ClaimedRun.of(run, None, packed)
        try:
            return claimed.prepared()
        except Exception:
            log.exception("the stored log of run %s cannot be prepared again", run_id)
            return None
