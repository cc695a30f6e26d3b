"""Accepting a run: resolve track and vehicle, de-duplicate, check, then process or queue.

Everything a client can get wrong is checked before anything is written, and the write is
one transaction: the track (if new), the run, its display signals, and either its full result
(short logs, processed inline, :func:`~app.services.run_lifecycle.store.complete_run`) or its
parsed input for the background worker.
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db.models import Run, Track
from app.services.context import AppContext
from app.services.errors import Conflict, Invalid
from app.services.lookup import (
    check_new_track_name,
    new_track_columns,
    resolve_track,
    resolve_vehicle,
)
from app.services.lookup import track_params as _track_params
from app.services.run_lifecycle.intake import Submission
from app.services.run_lifecycle.inversion import invert_now, start_early
from app.services.run_lifecycle.logs import pack_log, summarize
from app.services.run_lifecycle.processing import Processed
from app.services.run_lifecycle.store import NewRun, complete_run, insert_run
from app.services.track.centerlines import load_centerline, place_by_gnss
from app.services.vehicles.loads import declared_wheel_load, loaded_vehicle
from app.services.views.signals import log_signals
from engine.budget import TimeBudget
from engine.errors import EngineError, LogFormatError
from engine.positioning import Centerline
from engine.setup import PreparedRun, RunSetup, prepare_run
from engine.track import TrackParams
from engine.vehicle_kinds import Vehicle as EngineVehicle
from engine.vehicle_kinds import vehicle_from_dict

_inflight_guard = threading.Lock()
_inflight: dict[str, threading.Lock] = {}


@contextmanager
def _one_at_a_time(key: str) -> Iterator[None]:
    """Serialise identical submissions in this process: the second waits for the first and
    then finds its run (a duplicate), instead of inverting the same log again."""
    with _inflight_guard:
        lock = _inflight.setdefault(key, threading.Lock())
    with lock:
        yield
    with _inflight_guard:
        if not lock.locked():
            _inflight.pop(key, None)


def _existing(session: Session, sub: Submission, track: Track | None) -> Run | None:
    """A stored run this submission repeats (same Idempotency-Key, or same content on the track)."""
    if sub.idempotency_key:
        stored = sub.stored_idempotency_key
        prev = session.scalar(select(Run).where(Run.idempotency_key == stored))
        if prev is not None:
            same_track = track is not None and prev.track_id == track.id
            if prev.content_hash != sub.identity or not same_track:
                raise Conflict(
                    f"Idempotency-Key {sub.idempotency_key!r} was already used for run {prev.id} "
                    "with different content or track; use a new key for a new run",
                    field="Idempotency-Key",
                    run_id=prev.id,
                )
            return prev
    if track is not None:
        return session.scalar(
            select(Run).where(Run.track_id == track.id, Run.content_hash == sub.identity)
        )
    return None


def _preflight(
    sub: Submission, vehicle: EngineVehicle, track: TrackParams, placed: bool
) -> PreparedRun:
    # Everything that can be known about a log without inverting it (the engine's O(n)
    # pre-flight: speed, distance covered, sampling against the wavelength band), so that a
    # queued run does not fail later for a reason the client could have been told now. The
    # CSV reader made the log's plausibility checks ("csv" options) unless GNSS placed it.
    if sub.log.chainage_m is None and sub.start_chainage_m is None:
        gnss = (
            "the log has no GNSS fixes (latitude/longitude columns) to place it by"
            if sub.log.lat_deg is None or not sub.log.has_fixes
            else "the track has no centerline to place its GNSS fixes on (PUT "
            "/api/v1/tracks/{track}/centerline)"
        )
        raise Invalid(
            "start_chainage_m is required when the log has no chainage column and cannot be "
            f"placed by GNSS ({gnss}): give the chainage of the body centre at the first "
            "sample, m",
            field="start_chainage_m",
        )
    try:
        setup = RunSetup(sub.start_chainage_m, sub.direction, vehicle, track)
        return prepare_run(sub.log, setup, log_checked="csv" in sub.options and not placed)
    except EngineError as exc:
        # JSON arrays are named like a CSV's lines; the request field is "columns".
        json_columns = isinstance(exc, LogFormatError) and "columns" in sub.options
        raise Invalid.from_engine(exc, field="columns" if json_columns else None) from None


def submit(ctx: AppContext, sub: Submission) -> tuple[int, bool]:
    """Store a run (processed now if short, else queued); returns ``(run_id, created)``.

    ``created`` is False when the same run was stored before (same Idempotency-Key, or same
    content on the same track): nothing new is written then.

    Raises
    ------
    Invalid
        Unknown vehicles/tracks, missing start chainage and logs the engine rejects.
    Conflict
        A reused Idempotency-Key. Nothing is stored in either case.
    """
    try:
        for attempt in range(3):
            try:
                with _one_at_a_time(f"{ctx.db.url}|{sub.track}|{sub.track_id}|{sub.identity}"):
                    return _submit_once(ctx, sub)
            except IntegrityError:
                # A concurrent request stored the same track name or content first: look again.
                if attempt == 2:
                    raise Conflict(
                        "the run conflicts with one being stored at the same time; retry"
                    ) from None
        raise AssertionError("unreachable")
    finally:
        ctx.memory.busy()  # the upload's copies were just freed: kept while busy


@dataclass(frozen=True)
class _Found:
    """What the stored rows say about a new submission (read in one session)."""

    vehicle: EngineVehicle
    """The vehicle with the submission's load."""
    vehicle_id: int
    vehicle_version: int
    wheel_load_n: float | None
    """The static wheel load the run declares, N (None: the vehicle's own)."""
    track_fields: dict[str, Any] | None
    """The stored track's parameters (None: the submission creates its track)."""
    track_name: str | None
    line: Centerline | None
    failed_id: int | None
    """A failed run of the same content, replaced by this one."""


def _look_up(ctx: AppContext, sub: Submission) -> _Found | int:
    """The submission's vehicle and track, or the id of the stored run it repeats."""
    with ctx.db.session() as s:
        vehicle = resolve_vehicle(s, sub.vehicle, sub.vehicle_id)
        track = resolve_track(s, sub.track, sub.track_id)
        prev = _existing(s, sub, track)
        if prev is not None and prev.status != "failed":
            return prev.id
        wheel_load_n, load_field = declared_wheel_load(
            sub.log, sub.payload_kg, sub.static_wheel_load_n
        )
        vp = loaded_vehicle(
            vehicle_from_dict(vehicle.params_dict()), sub.payload_kg, wheel_load_n,
            field=load_field,
        )  # fmt: skip
        return _Found(
            vp, vehicle.id, vehicle.version, wheel_load_n,
            track.params_dict() if track is not None else None,
            track.name if track is not None else sub.track,
            load_centerline(s, track.id) if track is not None else None,
            prev.id if prev is not None else None,
        )  # fmt: skip


def _place(
    ctx: AppContext, sub: Submission, line: Centerline | None
) -> tuple[Submission, dict[str, Any] | None]:
    """The submission placed by its GNSS fixes on the track's centerline when it gives no
    start chainage, and the placement found (None: placed as given)."""
    if sub.start_chainage_m is not None or line is None or sub.log.lat_deg is None:
        return sub, None
    # The fixes and the odometer give start, direction and scale; a processing stage, so
    # under a processing slot and the processing budget.
    with ctx.slots:
        budget = TimeBudget(
            ctx.settings.processing_budget_s, "GNSS placement", "TRACKPROFILE_PROCESSING_BUDGET_S"
        )
        placed = place_by_gnss(sub.log, line, budget)
    assert placed.log.chainage_m is not None
    sub = dataclasses.replace(
        sub, log=placed.log, start_chainage_m=float(placed.log.chainage_m[0]),
        direction=placed.placement.direction,
    )  # fmt: skip
    return sub, placed.placement.to_dict()


def _new_run(
    ctx: AppContext, sub: Submission, found: _Found, positioning: dict[str, Any] | None,
    prepared: PreparedRun,
) -> tuple[NewRun, Processed | None]:  # fmt: skip
    """What the new run's rows hold (its packed log, summary, display signals), and its
    inversion when the log is short enough to be inverted in the request."""
    # The log is kept either way (reprocessing with a new vehicle version, calibration):
    # packed on a second thread meanwhile (Zstandard and numpy's copies release the GIL).
    with ThreadPoolExecutor(1, thread_name_prefix="pack-log") as pool:
        packing = pool.submit(pack_log, sub.log)
        summary = summarize(sub.log)
        signals, decimated = log_signals(sub.log)
        signals |= sub.extra_signals
        processed = None
        if sub.log.n <= ctx.settings.inline_max_samples:
            processed = invert_now(ctx, prepared)
        packed = packing.result()
    row = NewRun(
        sub, sub.identity, found.vehicle_id, found.wheel_load_n, positioning, summary,
        signals, decimated, packed,
    )  # fmt: skip
    return row, processed


def _queue(
    ctx: AppContext, s: Session, run_id: int, prepared: PreparedRun,
    started: Future[Processed] | None,
) -> None:  # fmt: skip
    """Commit a queued run, its parsed log handed to this process's worker (if it has one)."""
    handover = ctx.handover
    if handover is not None:
        # Before the commit: this process's worker may claim the run at once.
        handover.put(run_id, prepared, started)
    try:
        s.commit()
    except BaseException:
        if handover is not None:
            handover.take(run_id)
        raise


def _submit_once(ctx: AppContext, sub: Submission) -> tuple[int, bool]:
    settings = ctx.settings
    found = _look_up(ctx, sub)
    if isinstance(found, int):
        return found, False
    sub, positioning = _place(ctx, sub, found.line)
    if found.track_fields is None:
        check_new_track_name(sub.track)
    new_track = new_track_columns(sub.new_track) if found.track_fields is None else {}
    tp = TrackParams.from_dict(found.track_fields or _track_params(new_track))
    prepared = _preflight(sub, found.vehicle, tp, placed=positioning is not None)
    started = None
    if sub.log.n > settings.inline_max_samples and ctx.handover is not None:
        # Queued for this process's worker: its inversion starts now, beside the storing of
        # its input, and the worker takes the result (its claim and crash safety as for any
        # queued run).
        started = start_early(ctx, prepared)
    row, processed = _new_run(ctx, sub, found, positioning, prepared)
    with ctx.db.session() as s:
        if found.failed_id is not None:
            # A failed run of the same content is replaced by the new attempt.
            old = s.get(Run, found.failed_id)
            if old is not None:
                s.delete(old)
                s.flush()
        run = insert_run(s, row, found.track_name, new_track)
        run_id = run.id
        if processed is not None:
            complete_run(s, run, processed, found.vehicle_version,
                         auto_calibrate_runs=settings.auto_calibrate_runs)  # fmt: skip
        else:
            _queue(ctx, s, run_id, prepared, started)
    if processed is None or settings.auto_calibrate_runs:
        ctx.wake_worker()
    return run_id, True
