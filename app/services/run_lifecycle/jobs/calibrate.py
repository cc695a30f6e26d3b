"""Calibrating a vehicle: fit it on its stored runs and store the outcome."""

from __future__ import annotations

import logging
from typing import Any

from sqlalchemy import Update, update
from sqlalchemy.orm import Session

from app.db.base import utcnow
from app.db.models import Calibration
from app.services.errors import engine_error_facts
from app.services.run_lifecycle.jobs.base import Job, attempt, failure_facts
from app.services.run_lifecycle.lease import Claimable, Heartbeat
from app.services.run_lifecycle.store import updated
from app.services.vehicles.calibration import calibration_inputs, fit_calibration, store_calibration
from engine.errors import EngineError

log = logging.getLogger(__name__)

CALIBRATIONS = Claimable(
    Calibration, waiting=("queued", "running"), claimed_state="running",
    on_claim={"status": "running"}, on_release={"status": "queued"}, batch=4,
)  # fmt: skip
"""Calibration requests: ``queued``, or ``running`` under a claim."""


class CalibrateJob(Job):
    """Runs a claimed calibration under a processing slot (from the start when it was
    interrupted before: the fit keeps no partial state)."""

    claims = CALIBRATIONS

    def run(self, job_id: int) -> None:
        with self.ctx.slots:
            try:
                self._calibrate(job_id)
            except Exception as exc:
                # a failure outside the fit (its inputs, storing it) would otherwise repeat at
                # every retry and end as "interrupted repeatedly", its cause lost
                log.exception("calibration %s failed", job_id)
                with self.ctx.db.session() as s:
                    self._fail(s, job_id, failure_facts(exc, "calibrating"))

    def _calibrate(self, cal_id: int) -> None:
        with self.ctx.db.session() as s:
            cal = s.get(Calibration, cal_id)
            if cal is None or cal.claimed_by != self.crew.id:
                return
            if cal.attempts > self.ctx.settings.max_attempts:
                interrupted = {"message": "calibration was interrupted repeatedly",
                               "kind": "Interrupted"}  # fmt: skip
                self._fail(s, cal_id, interrupted)
                return
            request = dict(cal.request)
            try:
                vp, version, runs, t_from, t_to = calibration_inputs(s, cal)
            except EngineError as exc:  # e.g. a stored load that makes no vehicle
                self._fail(s, cal_id, engine_error_facts(exc))
                return

        def fit() -> dict[str, Any]:
            with Heartbeat.of(self.ctx, CALIBRATIONS, cal_id, self.crew.id):
                return fit_calibration(vp, runs, request)

        result = attempt(self.ctx, "calibrating", cal_id, self._fail, fit)
        if result is None:
            return
        with self.ctx.db.session() as s:
            if updated(s, self._owned(cal_id).values(heartbeat_at=utcnow())) != 1:
                s.rollback()
                return
            cal = s.get(Calibration, cal_id)
            assert cal is not None
            queued = store_calibration(s, cal, result, version, t_from, t_to)
            s.commit()
        if queued:
            self.crew.wake()

    def _owned(self, cal_id: int) -> Update:
        return update(Calibration).where(
            Calibration.id == cal_id, Calibration.claimed_by == self.crew.id,
            Calibration.status == "running",
        )  # fmt: skip

    def _fail(self, s: Session, cal_id: int, detail: dict[str, Any]) -> None:
        updated(
            s,
            update(Calibration)
            .where(Calibration.id == cal_id, Calibration.claimed_by == self.crew.id)
            .values(status="failed", error=detail, finished_at=utcnow()),
        )
        s.commit()
