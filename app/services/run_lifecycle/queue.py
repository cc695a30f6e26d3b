"""The database-backed queue: the worker's threads look for work and run the jobs of
:data:`~app.services.run_lifecycle.jobs.JOBS`, claiming their rows with
:mod:`~app.services.run_lifecycle.lease` (claim, heartbeat, recovery).

A queued run is a ``runs`` row with ``status='processing'`` and a ``run_inputs`` row; a
calibration request a ``calibrations`` row. Any number of workers, in any processes sharing
the database, claim them safely: one claim wins, a claim whose heartbeat stops is taken over,
and after ``max_attempts`` interruptions the job is marked failed (by the job).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import TypeVar

from app.services.context import AppContext
from app.services.run_lifecycle.handover import Handover
from app.services.run_lifecycle.jobs import JOBS, Job
from app.services.run_lifecycle.lease import Claimable, claim, new_owner, release_dead_claims

log = logging.getLogger(__name__)
J = TypeVar("J", bound=Job)


class Worker:
    """The processing threads of one app process, and its jobs (one of each kind)."""

    def __init__(self, ctx: AppContext) -> None:
        self.ctx = ctx
        self.id = new_owner()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self.jobs: dict[str, Job] = {name: kind(self) for name, kind in JOBS.items()}

    def job(self, kind: type[J]) -> J:
        """This worker's job of class ``kind``."""
        found = next(job for job in self.jobs.values() if type(job) is kind)
        assert isinstance(found, kind)
        return found

    # -- lifecycle -------------------------------------------------------------------------
    def start(self) -> None:
        """Release claims of dead local processes, then start the processing threads."""
        self.recover()
        self.ctx.handover = Handover()
        for i in range(self.ctx.settings.workers):
            t = threading.Thread(target=self._loop, name=f"run-worker-{i}", daemon=True)
            t.start()
            self._threads.append(t)

    def stop(self, timeout: float = 30.0) -> None:
        """Stop after the jobs in hand are finished (or ``timeout`` s)."""
        self._stop.set()
        self._wake.set()
        for t in self._threads:
            t.join(timeout)
        self._threads.clear()
        self.ctx.handover = None

    def wake(self) -> None:
        """Look for queued work now instead of at the next poll."""
        self._wake.set()

    @property
    def alive(self) -> bool:
        """True while every processing thread runs."""
        return bool(self._threads) and all(t.is_alive() for t in self._threads)

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                worked = self.run_once()
            except Exception:
                log.exception("run worker iteration failed")
                worked = False
            if not worked:
                self._wake.wait(self.ctx.settings.poll_interval_s)
                self._wake.clear()

    # -- claims ----------------------------------------------------------------------------
    def queues(self) -> list[Claimable]:
        """The tables whose rows the jobs claim."""
        return [job.claims for job in self.jobs.values() if job.claims is not None]

    def recover(self) -> int:
        """Free the claims (runs and calibrations) of processes on this host that no longer
        run; returns how many (:func:`~app.services.run_lifecycle.lease.release_dead_claims`)."""
        return release_dead_claims(self.ctx, self.id, self.queues())

    def claim(self, queue: Claimable) -> int | None:
        """Claim the oldest queued (or abandoned) row of ``queue``; None when there is none."""
        return claim(self.ctx, self.id, queue)

    def run_once(self) -> bool:
        """Do one job, trying the kinds in :data:`JOBS`' order: claim and run a queued row,
        else the first idle work that finds something; False when nothing was waiting."""
        looked_at = time.monotonic()
        for job in self.jobs.values():
            if job.claims is None:
                if job.look():
                    return True
                continue
            job_id = self.claim(job.claims)
            if job_id is None:
                job.unclaimed(looked_at)
                continue
            job.run(job_id)  # holds a processing slot while it works
            self.ctx.memory.busy()  # its freed arrays: kept for the next job while busy
            return True
        return False
