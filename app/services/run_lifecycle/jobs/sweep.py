"""Removing a run's detail past the retention policy, when the worker is idle."""

from __future__ import annotations

import logging
import threading
import time

from app.services.run_lifecycle.jobs.base import Crew, Job
from app.services.storage.retention import RetentionPolicy, sweep

log = logging.getLogger(__name__)


class SweepJob(Job):
    """Removes expired detail (:mod:`app.services.storage.retention`) when the last sweep is
    ``retention_interval_s`` old. Only one thread of the process sweeps at a time; several
    processes may (each run is removed once, under its track's lock)."""

    def __init__(self, crew: Crew) -> None:
        super().__init__(crew)
        self._next = 0.0  # time.monotonic() of the next sweep
        self._lock = threading.Lock()

    def look(self) -> bool:
        """Sweep when due; True when it removed something (more may be due)."""
        policy = RetentionPolicy.from_settings(self.ctx.settings)
        if not policy.active or time.monotonic() < self._next:
            return False
        if not self._lock.acquire(blocking=False):
            return False
        try:
            result = sweep(self.ctx.db, policy)
            if result.removed:
                log.info("retention: detail of %d runs expired, %d logs dropped",
                         result.expired_runs, result.dropped_logs)  # fmt: skip
            else:
                self._next = time.monotonic() + self.ctx.settings.retention_interval_s
            return result.removed > 0
        finally:
            self._lock.release()
