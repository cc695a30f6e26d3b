"""The worker's kinds of job, looked up in :data:`JOBS` (as the engine looks up ``METHODS``).

A new kind of job is one module here with a :class:`~.base.Job` subclass, and one entry in
:data:`JOBS`; the queue (:mod:`app.services.run_lifecycle.queue`) claims its rows (when it
names a table in ``claims``), keeps the claims alive and recovers them.
"""

from __future__ import annotations

from app.services.run_lifecycle.jobs.base import Crew, Job
from app.services.run_lifecycle.jobs.calibrate import CALIBRATIONS, CalibrateJob
from app.services.run_lifecycle.jobs.checkpoint import CheckpointJob
from app.services.run_lifecycle.jobs.long_level import LONG_LEVEL_GRACE_S, LongLevelJob
from app.services.run_lifecycle.jobs.process import HANDOVER_GRACE_S, RUNS, ProcessJob
from app.services.run_lifecycle.jobs.separate import SEPARATION_RETRY_S, SeparateJob
from app.services.run_lifecycle.jobs.sweep import SweepJob

JOBS: dict[str, type[Job]] = {
    "process": ProcessJob,
    "calibrate": CalibrateJob,
    "long_level": LongLevelJob,
    "separate": SeparateJob,
    "sweep": SweepJob,
    "checkpoint": CheckpointJob,
}
"""The worker's jobs by name, in the order a look tries them: queued runs first, then
calibrations; with neither waiting, the idle work (a waiting long level, a waiting separation,
the retention sweep, the WAL checkpoint)."""

__all__ = [
    "CALIBRATIONS", "HANDOVER_GRACE_S", "JOBS", "LONG_LEVEL_GRACE_S", "RUNS",
    "SEPARATION_RETRY_S", "CalibrateJob", "CheckpointJob", "Crew", "Job", "LongLevelJob",
    "ProcessJob", "SeparateJob", "SweepJob",
]  # fmt: skip
