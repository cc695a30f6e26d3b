"""Writing a run: its rows when it is accepted, its result when its inversion is finished.

The inline path (:mod:`~app.services.run_lifecycle.accept`) and the queued path (the process
job) store a finished inversion with the same :func:`complete_run`; each commits what it
writes in one transaction.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

from sqlalchemy import CursorResult, Update, delete, select, update
from sqlalchemy.orm import Session

from app.db.base import utcnow
from app.db.models import Run, RunInput, RunSignals, Track
from app.services.run_lifecycle.intake import Submission, clean_filename
from app.services.run_lifecycle.logs import LogSummary
from app.services.run_lifecycle.processing import Processed, store_result
from app.services.track.integrate import Separation
from app.services.vehicles.calibration import maybe_auto_calibrate
from app.services.views.signals import pack_signals
from engine.vehicle_plausibility import ImplausibleResult


@dataclass(frozen=True)
class NewRun:
    """What an accepted submission stores besides its own fields (all checked already)."""

    sub: Submission
    identity: str
    """The content hash of the log as the client sent it (GNSS placement changes the log,
    not its identity)."""
    vehicle_id: int
    static_wheel_load_n: float | None
    positioning: dict[str, Any] | None
    summary: LogSummary
    signals: dict[str, Any]
    decimated: bool
    packed_log: bytes


def insert_run(
    session: Session, new: NewRun, track_name: str | None, new_track: dict[str, Any]
) -> Run:
    """Add an accepted run (queued), its display signals and its log, creating its track from
    ``new_track``'s columns when no track has that name (flushed; the caller commits)."""
    sub, summary = new.sub, new.summary
    track_row = session.scalar(select(Track).where(Track.name == track_name))
    if track_row is None:
        track_row = Track(name=track_name, **new_track)
        session.add(track_row)
        session.flush()
    run = Run(
        name=sub.name,
        track_id=track_row.id,
        vehicle_id=new.vehicle_id,
        source=sub.source,
        original_filename=clean_filename(sub.filename),
        recorded_at=sub.recorded_at,
        start_chainage_m=sub.start_chainage_m,
        direction=sub.direction,
        sample_rate_hz=summary.sample_rate_hz,
        n_samples=summary.n_samples,
        duration_s=summary.duration_s,
        speed_min_mps=summary.speed_min_mps,
        speed_max_mps=summary.speed_max_mps,
        chainage_offset_m=0.0,
        status="processing",
        stage="queued",
        options=sub.options,
        content_hash=new.identity,
        positioning=new.positioning,
        idempotency_key=sub.stored_idempotency_key,
        attempts=0,
        payload_kg=sub.payload_kg,
        static_wheel_load_n=new.static_wheel_load_n,
    )
    session.add(run)
    session.flush()
    signals = new.signals
    session.add(
        RunSignals(
            run_id=run.id,
            n_points=len(signals["time_s"]),
            decimated=new.decimated,
            packed=pack_signals(signals),
        )
    )
    session.add(RunInput(run_id=run.id, data=new.packed_log))
    return run


def complete_run(
    session: Session,
    run: Run,
    processed: Processed,
    vehicle_version: int | None,
    *,
    auto_calibrate_runs: int,
    separation: Separation = "now",
) -> None:
    """Store a finished inversion of ``run`` (profile, soft spots, the track's aggregate; the
    separation ``"now"`` or marked for ``"later"``), commit, then queue the vehicle's
    calibration when ``auto_calibrate_runs`` runs have come since its last one.

    ``vehicle_version`` is the vehicle parameter version the result was computed with.
    """
    store_result(session, run, processed, vehicle_version, separation=separation)
    vehicle_id = run.vehicle_id
    session.commit()
    maybe_auto_calibrate(session, vehicle_id, auto_calibrate_runs)


def updated(session: Session, statement: Update) -> int:
    """Execute an UPDATE in the session's transaction; the number of rows it changed."""
    result = cast("CursorResult[Any]", session.execute(statement))
    return int(result.rowcount)


def fail_run(session: Session, run_id: int, owner: str, detail: dict[str, Any]) -> None:
    """Mark run ``run_id`` failed with ``detail`` while ``owner`` holds its claim; commit."""
    # A run that had a result (reprocessed after a vehicle edit), or whose result the
    # vehicle made implausible, keeps its log: restoring the vehicle must bring it back.
    had_result = session.scalar(select(Run.vehicle_version).where(Run.id == run_id)) is not None
    failed = updated(
        session,
        update(Run)
        .where(Run.id == run_id, Run.claimed_by == owner, Run.status == "processing")
        .values(status="failed", stage=None, error=detail, processed_at=utcnow()),
    )
    if failed == 1 and not had_result and detail.get("kind") != ImplausibleResult.__name__:
        session.execute(delete(RunInput).where(RunInput.run_id == run_id))
    session.commit()
