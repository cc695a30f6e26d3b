"""Retention: a run's detail is kept for a while, what the track learned from it for ever.

Detail is what a run costs per km: its profile (``run_profile_blocks``: each axle's level,
the baseline, each axle's wheel force), its display signals and its stored log. It goes when
the run is older than ``detail_retention_days`` or not among the newest
``detail_retention_runs`` processed runs of its track (either, when both are set; neither by
default). Kept for ever: the run's metadata and soft spots, its aligned level and wheel force
on the track grid (``track_run_levels``, from which the aggregate and the geometry/stiffness
separation are recomputed, so neither changes when detail expires), the aggregate, the
register, alignment and calibrations.

The stored log (~0.6 MB per km of a 1 kHz log even compressed: ten times everything else)
is only needed to reprocess a run with new vehicle parameters or to calibrate the vehicle: it
is kept for the newest ``log_retention_runs`` processed runs of each vehicle (at least
``auto_calibrate_runs``), and goes with the rest of the detail at the latest.

The worker sweeps in small transactions, one run each, under the track's lock (as a run being
stored or a realignment holds it), so nothing that reads a track's runs under that lock sees a
run half removed. Readers of a run's detail read it with one statement and check the run's
``detail_expired_at`` before and after (:func:`require_detail`): they get the whole detail or
410, never part of it.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any, cast

from sqlalchemy import CursorResult, delete, func, select, update
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.base import utcnow
from app.db.models import Run, RunInput, RunProfileBlock, RunSignals
from app.db.session import Database
from app.services.errors import Gone
from app.services.track.integrate import lock_track

SWEEP_BATCH = 50
"""Runs looked at per sweep query; each is then removed in its own transaction."""


@dataclass(frozen=True)
class RetentionPolicy:
    """How long a run's detail and log are kept (None: for ever)."""

    detail_days: float | None = None
    """Days after the run's recording (upload time when unknown)."""
    detail_runs: int | None = None
    """Newest processed runs per track that keep their detail."""
    log_runs: int | None = None
    """Newest processed runs per vehicle that keep their log (None: all with detail)."""

    @classmethod
    def from_settings(cls, settings: Settings) -> RetentionPolicy:
        """The policy the service is configured with (``TRACKPROFILE_*_RETENTION_*``)."""
        log_runs = settings.log_retention_runs
        if log_runs is not None:
            log_runs = max(log_runs, settings.auto_calibrate_runs)
        return cls(settings.detail_retention_days, settings.detail_retention_runs, log_runs)

    @property
    def active(self) -> bool:
        """True when anything is ever removed."""
        return any(v is not None for v in (self.detail_days, self.detail_runs, self.log_runs))

    def describe(self) -> str:
        """The policy in words (for the 410 message)."""
        parts = []
        if self.detail_days is not None:
            parts.append(f"{self.detail_days:g} days")
        if self.detail_runs is not None:
            parts.append(f"the newest {self.detail_runs} runs of each track")
        return " or ".join(parts) if parts else "the retention policy"


def _when() -> Any:
    return func.coalesce(Run.recorded_at, Run.created_at)


def runs_due(session: Session, policy: RetentionPolicy, now: datetime, limit: int) -> list[int]:
    """Processed runs whose detail the policy removes now (at most ``limit``, oldest first)."""
    kept = (Run.status == "done", Run.detail_expired_at.is_(None))
    due: set[int] = set()
    if policy.detail_days is not None:
        cutoff = now - timedelta(days=policy.detail_days)
        due.update(
            session.scalars(
                select(Run.id).where(*kept, _when() < cutoff).order_by(Run.id).limit(limit)
            )
        )
    if policy.detail_runs is not None:
        rank = (
            func.row_number()
            .over(partition_by=Run.track_id, order_by=(_when().desc(), Run.id.desc()))
            .label("rank")
        )
        ranked = select(Run.id, rank).where(Run.status == "done").subquery()
        due.update(
            session.scalars(
                select(ranked.c.id)
                .join(Run, Run.id == ranked.c.id)
                .where(ranked.c.rank > policy.detail_runs, Run.detail_expired_at.is_(None))
                .order_by(ranked.c.id)
                .limit(limit)
            )
        )
    return sorted(due)[:limit]


def logs_due(session: Session, policy: RetentionPolicy, limit: int) -> list[int]:
    """Processed runs whose stored log the policy removes now (beyond the newest
    ``log_runs`` processed runs of their vehicle), at most ``limit``."""
    if policy.log_runs is None:
        return []
    rank = func.row_number().over(partition_by=Run.vehicle_id, order_by=Run.id.desc()).label("rank")
    ranked = select(Run.id, rank).where(Run.status == "done").subquery()
    return list(
        session.scalars(
            select(ranked.c.id)
            .join(RunInput, RunInput.run_id == ranked.c.id)
            .where(ranked.c.rank > policy.log_runs)
            .order_by(ranked.c.id)
            .limit(limit)
        )
    )


def _rowcount(session: Session, statement: Any) -> int:
    return int(cast("CursorResult[Any]", session.execute(statement)).rowcount)


def expire_detail(session: Session, run_id: int, now: datetime | None = None) -> bool:
    """Remove one processed run's detail and mark it expired (caller commits); False when
    the run is gone, not processed or already expired."""
    track_id = session.scalar(select(Run.track_id).where(Run.id == run_id))
    if track_id is None:
        return False
    lock_track(session, track_id)
    marked = _rowcount(
        session,
        update(Run)
        .where(Run.id == run_id, Run.status == "done", Run.detail_expired_at.is_(None))
        .values(detail_expired_at=now or utcnow()),
    )
    if marked != 1:
        return False
    for model in (RunProfileBlock, RunSignals, RunInput):
        session.execute(delete(model).where(model.run_id == run_id))
    return True


def drop_log(session: Session, run_id: int) -> bool:
    """Remove a processed run's stored log (caller commits); False when it had none."""
    return (
        _rowcount(
            session,
            delete(RunInput).where(
                RunInput.run_id == run_id,
                RunInput.run_id.in_(select(Run.id).where(Run.status == "done")),
            ),
        )
        == 1
    )


@dataclass(frozen=True)
class SweepResult:
    """What one sweep removed."""

    expired_runs: int
    dropped_logs: int

    @property
    def removed(self) -> int:
        """Runs touched."""
        return self.expired_runs + self.dropped_logs


def sweep(db: Database, policy: RetentionPolicy, now: datetime | None = None) -> SweepResult:
    """Remove what the policy says has expired, up to :data:`SWEEP_BATCH` runs of each kind,
    one transaction per run (call again while it removes something)."""
    if not policy.active:
        return SweepResult(0, 0)
    now = now or utcnow()
    with db.session() as s:
        runs = runs_due(s, policy, now, SWEEP_BATCH)
        logs = logs_due(s, policy, SWEEP_BATCH)
    expired = dropped = 0
    for run_id in runs:
        with db.session() as s:
            if expire_detail(s, run_id, now):
                expired += 1
            s.commit()
    for run_id in logs:
        with db.session() as s:
            if drop_log(s, run_id):
                dropped += 1
            s.commit()
    return SweepResult(expired, dropped)


def expired_message(run_id: int, what: str, when: datetime | None) -> str:
    """Why a run's detail cannot be served."""
    at = f" on {when:%Y-%m-%d %H:%M} UTC" if when is not None else ""
    return (
        f"run {run_id}'s {what} has expired{at} under the retention policy (profile, signals "
        "and log are kept for a configured time or number of runs); its metadata, soft spots "
        "and its share of the track's aggregate and register are kept"
    )


def require_detail(session: Session, run: Run, what: str) -> None:
    """Raise :class:`Gone` when the run's detail has expired, as stored now (not as the
    session's copy of the run says: a sweep may have committed since it was read)."""
    expired = run.detail_expired_at or session.scalar(
        select(Run.detail_expired_at).where(Run.id == run.id)
    )
    if expired is not None:
        raise Gone(expired_message(run.id, what, expired), field="run_id", expired_at=_iso(expired))


def _iso(when: datetime | None) -> str | None:
    return None if when is None else when.isoformat()
