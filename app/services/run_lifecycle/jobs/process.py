"""Processing a queued run: invert its log, store the result, then its long level, separate
its track."""

from __future__ import annotations

import logging
from datetime import datetime
from typing import Any

from sqlalchemy import Update, select, update
from sqlalchemy.orm import Session

from app.db.base import utcnow
from app.db.models import Run, RunInput
from app.services.run_lifecycle.inversion import ClaimedRun, invert_claimed
from app.services.run_lifecycle.jobs.base import Job, attempt
from app.services.run_lifecycle.jobs.long_level import LongLevelJob
from app.services.run_lifecycle.jobs.separate import SeparateJob
from app.services.run_lifecycle.lease import Claimable, Heartbeat
from app.services.run_lifecycle.processing import Processed
from app.services.run_lifecycle.store import complete_run, fail_run, updated

log = logging.getLogger(__name__)

RUNS = Claimable(
    Run, waiting=("processing",), claimed_state="processing",
    on_claim={"stage": "inverting"}, on_release={"stage": "queued"},
)  # fmt: skip
"""Queued runs: ``status='processing'`` with a ``run_inputs`` row."""

HANDOVER_GRACE_S = 5.0
"""A held log younger than this survives a look that found no claimable run, s."""


class ProcessJob(Job):
    """Inverts a claimed run and stores the outcome (done, or failed with its cause)."""

    claims = RUNS

    def unclaimed(self, looked_at: float) -> None:
        # Their runs went elsewhere: free the memory (not the newest: a run claimed by
        # another thread of this process takes its entry a moment after claiming it).
        if (handover := self.ctx.handover) is not None:
            handover.drop_before(looked_at - HANDOVER_GRACE_S)

    def run(self, job_id: int) -> None:
        claimed = self._claimed(job_id)
        if claimed is None:
            return

        def work() -> Processed:
            with Heartbeat.of(self.ctx, RUNS, job_id, self.crew.id):
                return invert_claimed(self.ctx, claimed)

        processed = attempt(self.ctx, "processing", job_id, self._fail, work)
        if processed is None:
            return
        stored = self._store(job_id, processed, claimed.vehicle_version)
        if stored is None:
            return
        track_id, processed_at = stored
        # the run is answered done: its long level (D2's) and the separation follow
        if processed.later is not None:
            self.crew.job(LongLevelJob).complete(job_id, processed_at, processed.later)
        self.crew.job(SeparateJob).separate_track(track_id)

    def _claimed(self, run_id: int) -> ClaimedRun | None:
        """The claimed run's set-up and log; None (and the run failed) when it cannot be
        processed, or when the claim is no longer this worker's."""
        with self.ctx.db.session() as s:
            run = s.get(Run, run_id)
            if run is None or run.claimed_by != self.crew.id:
                return None
            log.info("claimed run %s (attempt %d) by %s", run_id, run.attempts, self.crew.id)
            if run.attempts > self.ctx.settings.max_attempts:
                times = "once" if run.attempts == 2 else f"{run.attempts - 1} times"
                self._fail(s, run_id, {
                    "message": f"processing was interrupted {times} (the service stopped "
                    "while working on it); upload the run again to retry",
                    "kind": "Interrupted",
                })  # fmt: skip
                return None
            # The log the request of this process parsed and checked, else the stored one.
            handover = self.ctx.handover
            handed = None if handover is None else handover.take(run_id)
            packed = None
            if handed is None:
                packed = s.scalar(select(RunInput.data).where(RunInput.run_id == run_id))
                if packed is None:
                    lost = {"message": "the run's stored input is missing", "kind": "Lost"}
                    self._fail(s, run_id, lost)
                    return None
            return ClaimedRun.of(run, handed, packed)

    def _store(
        self, run_id: int, processed: Processed, vehicle_version: int
    ) -> tuple[int, datetime | None] | None:
        """Store the result (computed with ``vehicle_version``) while the claim is still this
        worker's; the run's track id and its ``processed_at`` as stored (None: the run was
        deleted or taken over meanwhile, the result is dropped)."""
        # The stage is committed on its own, so that clients see "storing" while the store
        # (which may wait for the track's lock) runs.
        with self.ctx.db.session() as s:
            updated(s, self._owned(run_id).values(stage="storing", heartbeat_at=utcnow()))
            s.commit()
        with self.ctx.db.session() as s:
            # The UPDATE takes the write lock first and proves the claim is still ours: then
            # everything is written at once.
            if updated(s, self._owned(run_id).values(heartbeat_at=utcnow())) != 1:
                s.rollback()
                log.info("run %s was deleted or taken over while processing; result dropped",
                         run_id)  # fmt: skip
                return None
            run = s.get(Run, run_id)
            assert run is not None
            track_id = run.track_id
            # done without waiting for the track's separation: redone next, on its own
            complete_run(
                s, run, processed, vehicle_version,
                auto_calibrate_runs=self.ctx.settings.auto_calibrate_runs, separation="later",
            )  # fmt: skip
            processed_at = s.scalar(select(Run.processed_at).where(Run.id == run_id))
        return track_id, processed_at

    def _owned(self, run_id: int) -> Update:
        """An UPDATE of run ``run_id`` while this worker still owns its processing."""
        return update(Run).where(
            Run.id == run_id, Run.claimed_by == self.crew.id, Run.status == "processing"
        )

    def _fail(self, s: Session, run_id: int, detail: dict[str, Any]) -> None:
        fail_run(s, run_id, self.crew.id, detail)
