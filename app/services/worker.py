"""Background processing of queued runs, safe with several app processes on one database.

A queued run is a ``runs`` row with ``status='processing'`` and a ``run_inputs`` row. A worker
claims it with one atomic ``UPDATE ... WHERE claimed_by IS NULL OR heartbeat_at < stale``
(only one process can win), keeps the claim alive with a heartbeat while the engine runs, and
stores the result in one transaction that first re-checks it still owns the claim. A process
that dies leaves a claim whose heartbeat stops: another worker (or this host after a restart)
takes the run over; after ``max_attempts`` interruptions the run is marked failed.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
import uuid
from collections.abc import Callable
from datetime import timedelta
from typing import Any, TypeVar, cast

from sqlalchemy import CursorResult, Update, delete, or_, select, update
from sqlalchemy.orm import Session

from app.db.base import utcnow
from app.db.models import Calibration, Run, RunInput
from app.services.errors import engine_error_facts
from engine.errors import EngineError
from engine.setup import PreparedRun, RunSetup, prepare_run
from engine.track import TrackParams
from engine.vehicle_kinds import vehicle_from_dict
from engine.vehicle_plausibility import ImplausibleResult

from .calibration import (
    calibration_inputs,
    fit_calibration,
    maybe_auto_calibrate,
    store_calibration,
)
from .context import AppContext
from .handover import Handover
from .integrate import separate_pending, tracks_pending_separation
from .loads import loaded_vehicle
from .logs import unpack_log
from .processing import Processed, invert, store_result
from .retention import RetentionPolicy, sweep

log = logging.getLogger(__name__)
T = TypeVar("T")


def _rowcount(session: Session, statement: Update) -> int:
    """Execute an UPDATE in the session's transaction; the number of rows it changed."""
    result = cast("CursorResult[Any]", session.execute(statement))
    return int(result.rowcount)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _failure_facts(exc: Exception, doing: str) -> dict[str, Any]:
    """What a job that failed records: an engine error by its facts, anything else as an
    internal error with the exception's message (its cause, for whoever reads the job)."""
    if isinstance(exc, EngineError):
        return engine_error_facts(exc)
    cause = str(exc)[:500]
    return {
        "message": f"internal error while {doing} ({type(exc).__name__}"
        + (f": {cause})" if cause else ")"),
        "kind": "InternalError",
    }


class Heartbeat:
    """Refreshes a claim (a run's, or a calibration's) every ``interval`` seconds until stopped."""

    def __init__(
        self,
        ctx: AppContext,
        run_id: int,
        owner: str,
        interval: float,
        model: type[Run] | type[Calibration] = Run,
    ) -> None:
        self.ctx, self.run_id, self.owner, self.interval = ctx, run_id, owner, interval
        self.model = model
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, name=f"heartbeat-{run_id}", daemon=True)

    def __enter__(self) -> Heartbeat:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def _beat(self) -> None:
        while not self._stop.wait(self.interval):
            try:
                with self.ctx.db.engine.begin() as conn:
                    m = self.model
                    conn.execute(
                        update(m)
                        .where(m.id == self.run_id, m.claimed_by == self.owner)
                        .values(heartbeat_at=utcnow())
                    )
            except Exception:  # a missed beat only shortens the lease
                log.warning("heartbeat of %s %s failed", self.model.__tablename__, self.run_id,
                            exc_info=True)  # fmt: skip


SEPARATION_RETRY_S = 60.0
"""A track whose waiting separation failed is tried again after this long, s."""

HANDOVER_GRACE_S = 5.0
"""A held log younger than this survives a look that found no claimable run, s."""


class Worker:
    """Processing threads of one app process."""

    def __init__(self, ctx: AppContext) -> None:
        self.ctx = ctx
        self.id = f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._next_sweep = 0.0  # time.monotonic() of the next retention sweep
        self._separation_failed: dict[int, float] = {}  # track id: time.monotonic() of it
        self._sweep_lock = threading.Lock()
        self._checkpoint_lock = threading.Lock()

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
        """Stop after the runs in hand are finished (or ``timeout`` s)."""
        self._stop.set()
        self._wake.set()
        for t in self._threads:
            t.join(timeout)
        self._threads.clear()
        self.ctx.handover = None

    def wake(self) -> None:
        """Look for queued runs now instead of at the next poll."""
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

    # -- claiming --------------------------------------------------------------------------
    def recover(self) -> int:
        """Free the claims (runs and calibrations) of processes on this host that no longer
        run; returns how many.

        Their runs (calibrations) are then taken by the next free worker and processed from
        their stored input (calibrated from the start). Claims of other hosts are left to
        expire (``lease_s``).
        """
        host = socket.gethostname()
        freed = 0
        # (claimed thing, its state while claimed, what frees the claim)
        kinds: list[tuple[type[Run] | type[Calibration], str, dict[str, Any]]] = [
            (Run, "processing", {"claimed_by": None, "stage": "queued"}),
            (Calibration, "running", {"claimed_by": None, "status": "queued"}),
        ]
        with self.ctx.db.engine.begin() as conn:
            for model, state, free in kinds:
                rows = conn.execute(
                    select(model.id, model.claimed_by).where(
                        model.status == state, model.claimed_by.is_not(None)
                    )
                ).all()
                for row_id, owner in rows:
                    if self._dead_local(owner, host):
                        res = conn.execute(
                            update(model)
                            .where(model.id == row_id, model.claimed_by == owner)
                            .values(**free)
                        )
                        freed += res.rowcount
        if freed:
            log.warning("resuming %d run(s)/calibration(s) interrupted by a stopped process", freed)
        return freed

    def _dead_local(self, owner: object, host: str) -> bool:
        """True for a claim of another process on this host that no longer runs."""
        parts = str(owner).split(":")
        if len(parts) != 3 or parts[0] != host or owner == self.id:
            return False
        try:
            pid = int(parts[1])
        except ValueError:
            return False
        return pid == os.getpid() or not _pid_alive(pid)

    def claim(self) -> int | None:
        """Claim the oldest queued (or abandoned) run; None when there is none."""
        now = utcnow()
        stale = now - timedelta(seconds=self.ctx.settings.lease_s)
        free = or_(Run.claimed_by.is_(None), Run.heartbeat_at < stale)
        with self.ctx.db.engine.connect() as conn:
            candidates = (
                conn.execute(
                    select(Run.id).where(Run.status == "processing", free).order_by(Run.id).limit(8)
                )
                .scalars()
                .all()
            )
        for run_id in candidates:
            with self.ctx.db.engine.begin() as conn:
                res = conn.execute(
                    update(Run)
                    .where(Run.id == run_id, Run.status == "processing", free)
                    .values(
                        claimed_by=self.id,
                        heartbeat_at=now,
                        attempts=Run.attempts + 1,
                        stage="inverting",
                    )
                )
            if res.rowcount == 1:
                return int(run_id)
        return None

    def run_once(self) -> bool:
        """Claim and process one run, else one calibration; False when nothing was waiting."""
        looked_at = time.monotonic()
        run_id = self.claim()
        if run_id is None and (handover := self.ctx.handover) is not None:
            # Their runs went elsewhere: free the memory (not the newest: a run claimed by
            # another thread of this process takes its entry a moment after claiming it).
            handover.drop_before(looked_at - HANDOVER_GRACE_S)
        if run_id is not None:
            self.process(run_id)  # holds a processing slot while it inverts
            self.ctx.memory.busy()  # its freed arrays: kept for the next run while busy
            return True
        cal_id = self.claim_calibration()
        if cal_id is None:
            if self.separate_waiting() or self.sweep_if_due():
                return True
            self.checkpoint_when_idle()
            return False
        with self.ctx.slots:
            try:
                self.calibrate(cal_id)
            except Exception as exc:
                # a failure outside the fit (its inputs, storing it) would otherwise repeat at
                # every retry and end as "interrupted repeatedly", its cause lost
                log.exception("calibration %s failed", cal_id)
                with self.ctx.db.session() as s:
                    self._fail_calibration(s, cal_id, _failure_facts(exc, "calibrating"))
        self.ctx.memory.busy()
        return True

    def checkpoint_when_idle(self) -> None:
        """With nothing left to do, move the WAL's pages into the SQLite database file (not
        at a request's commit: see ``SQLITE_AUTOCHECKPOINT_PAGES``). Cheap when there is
        nothing to copy; one thread of the process at a time."""
        if not self._checkpoint_lock.acquire(blocking=False):
            return
        try:
            self.ctx.db.checkpoint()
        except Exception:  # a busy or locked database: the next idle moment tries again
            log.warning("WAL checkpoint failed", exc_info=True)
        finally:
            self._checkpoint_lock.release()

    def sweep_if_due(self) -> bool:
        """Remove expired detail (``app.services.retention``) when the last sweep is
        ``retention_interval_s`` old; True when it removed something (more may be due).
        Only one thread of the process sweeps at a time; several processes may (each run is
        removed once, under its track's lock)."""
        policy = RetentionPolicy.from_settings(self.ctx.settings)
        if not policy.active or time.monotonic() < self._next_sweep:
            return False
        if not self._sweep_lock.acquire(blocking=False):
            return False
        try:
            result = sweep(self.ctx.db, policy)
            if result.removed:
                log.info("retention: detail of %d runs expired, %d logs dropped",
                         result.expired_runs, result.dropped_logs)  # fmt: skip
            else:
                self._next_sweep = time.monotonic() + self.ctx.settings.retention_interval_s
            return result.removed > 0
        finally:
            self._sweep_lock.release()

    # -- calibrations ----------------------------------------------------------------------
    def claim_calibration(self) -> int | None:
        """Claim the oldest queued (or abandoned) calibration; None when there is none."""
        now = utcnow()
        stale = now - timedelta(seconds=self.ctx.settings.lease_s)
        free = or_(Calibration.claimed_by.is_(None), Calibration.heartbeat_at < stale)
        active = Calibration.status.in_(("queued", "running"))
        with self.ctx.db.engine.connect() as conn:
            candidates = conn.execute(
                select(Calibration.id).where(active, free).order_by(Calibration.id).limit(4)
            ).scalars().all()  # fmt: skip
        for cal_id in candidates:
            with self.ctx.db.engine.begin() as conn:
                res = conn.execute(
                    update(Calibration)
                    .where(Calibration.id == cal_id, active, free)
                    .values(claimed_by=self.id, heartbeat_at=now, status="running",
                            attempts=Calibration.attempts + 1)
                )  # fmt: skip
            if res.rowcount == 1:
                return int(cal_id)
        return None

    def calibrate(self, cal_id: int) -> None:
        """Run a calibration this worker has claimed and store the outcome (from the start
        when it was interrupted before: the fit keeps no partial state)."""
        settings = self.ctx.settings
        with self.ctx.db.session() as s:
            cal = s.get(Calibration, cal_id)
            if cal is None or cal.claimed_by != self.id:
                return
            if cal.attempts > settings.max_attempts:
                self._fail_calibration(
                    s, cal_id, {"message": "calibration was interrupted repeatedly",
                                "kind": "Interrupted"},
                )  # fmt: skip
                return
            request = dict(cal.request)
            try:
                vp, version, runs, t_from, t_to = calibration_inputs(s, cal)
            except EngineError as exc:  # e.g. a stored load that makes no vehicle
                self._fail_calibration(s, cal_id, engine_error_facts(exc))
                return

        def fit() -> dict[str, Any]:
            with Heartbeat(
                self.ctx, cal_id, self.id, max(0.5, settings.lease_s / 4), model=Calibration
            ):
                return fit_calibration(vp, runs, request)

        result = self._attempt("calibrating", cal_id, self._fail_calibration, fit)
        if result is None:
            return
        with self.ctx.db.session() as s:
            owned = _rowcount(
                s,
                update(Calibration)
                .where(Calibration.id == cal_id, Calibration.claimed_by == self.id,
                       Calibration.status == "running")
                .values(heartbeat_at=utcnow()),
            )  # fmt: skip
            if owned != 1:
                s.rollback()
                return
            cal = s.get(Calibration, cal_id)
            assert cal is not None
            queued = store_calibration(s, cal, result, version, t_from, t_to)
            s.commit()
        if queued:
            self.wake()

    def _attempt(
        self,
        doing: str,
        job_id: int,
        fail: Callable[[Session, int, dict[str, Any]], None],
        work: Callable[[], T],
    ) -> T | None:
        """Run a claimed job's numerics; when they fail, record why with ``fail`` (an engine
        error by its facts, anything else as an internal error, logged) and return None."""
        try:
            return work()
        except EngineError as exc:
            facts = engine_error_facts(exc)
        except Exception as exc:
            log.exception("%s %s failed", doing, job_id)
            facts = _failure_facts(exc, doing)
        with self.ctx.db.session() as s:
            fail(s, job_id, facts)
        return None

    def _fail_calibration(self, s: Session, cal_id: int, detail: dict[str, Any]) -> None:
        _rowcount(
            s,
            update(Calibration)
            .where(Calibration.id == cal_id, Calibration.claimed_by == self.id)
            .values(status="failed", error=detail, finished_at=utcnow()),
        )
        s.commit()

    # -- processing ------------------------------------------------------------------------
    def process(self, run_id: int) -> None:
        """Process a run this worker has claimed and store the outcome."""
        settings = self.ctx.settings
        with self.ctx.db.session() as s:
            run = s.get(Run, run_id)
            if run is None or run.claimed_by != self.id:
                return
            log.info("claimed run %s (attempt %d) by %s", run_id, run.attempts, self.id)
            if run.attempts > settings.max_attempts:
                times = "once" if run.attempts == 2 else f"{run.attempts - 1} times"
                self._fail(
                    s,
                    run_id,
                    {
                        "message": f"processing was interrupted {times} (the service stopped "
                        "while working on it); upload the run again to retry",
                        "kind": "Interrupted",
                    },
                )
                return
            # The log the request of this process parsed and checked, else the stored one.
            handover = self.ctx.handover
            handed = None if handover is None else handover.take(run_id)
            data = (
                None
                if handed is not None
                else s.scalar(select(RunInput.data).where(RunInput.run_id == run_id))
            )
            vp = loaded_vehicle(
                vehicle_from_dict(run.vehicle.params_dict()), run.payload_kg,
                run.static_wheel_load_n,
            )  # fmt: skip
            vehicle_version, vehicle_id = run.vehicle.version, run.vehicle_id
            tp = TrackParams.from_dict(run.track.params_dict())
            setup = RunSetup(run.start_chainage_m, run.direction, vp, tp)
        if data is None and handed is None:
            with self.ctx.db.session() as s:
                self._fail(
                    s, run_id, {"message": "the run's stored input is missing", "kind": "Lost"}
                )
            return
        held = [data]  # the stored log is freed once unpacked, before the inversion runs
        del data

        def work() -> Processed:
            with Heartbeat(self.ctx, run_id, self.id, max(0.5, settings.lease_s / 4)):
                started = None if handed is None else handed.started_for(setup)
                if started is not None:
                    # The request's inversion (holding its own slot) of the same set-up; a
                    # vehicle version or start changed since inverts again.
                    return started.result()
                with self.ctx.slots:
                    return invert(prepared(), settings.processing_budget_s)

        def prepared() -> PreparedRun:
            if handed is not None:
                # Prepared by the submission (for another set-up: prepared again, the log's
                # plausibility not checked twice).
                return handed.prepared.with_setup(setup)
            packed = held.pop()
            assert packed is not None
            return prepare_run(unpack_log(packed), setup)

        processed = self._attempt("processing", run_id, self._fail, work)
        if processed is None:
            return
        # The stage is committed on its own, so that clients see "storing" while the store
        # (which may wait for the track's lock) runs.
        with self.ctx.db.session() as s:
            _rowcount(s, self._owned(run_id).values(stage="storing", heartbeat_at=utcnow()))
            s.commit()
        with self.ctx.db.session() as s:
            # The UPDATE takes the write lock first and proves the claim is still ours (the run
            # may have been deleted or taken over meanwhile): then everything is written at once.
            owned = _rowcount(s, self._owned(run_id).values(heartbeat_at=utcnow()))
            if owned != 1:
                s.rollback()
                log.info(
                    "run %s was deleted or taken over while processing; result dropped", run_id
                )
                return
            run = s.get(Run, run_id)
            assert run is not None
            # done without waiting for the track's separation: redone next, on its own
            store_result(s, run, processed, vehicle_version, separation="later")
            track_id = run.track_id
            s.commit()
        self.separate_track(track_id)
        with self.ctx.db.session() as s:
            maybe_auto_calibrate(s, vehicle_id, settings.auto_calibrate_runs)

    def separate_track(self, track_id: int) -> bool:
        """Redo the separation a stored run left waiting on track ``track_id`` (one
        transaction, :func:`~app.services.integrate.separate_pending`); False when none was
        waiting or it failed (logged; the mark stays, retried at a later idle look)."""
        try:
            with self.ctx.db.session() as s:
                done = separate_pending(s, track_id)
                s.commit()
        except Exception:
            log.exception("separation of track %s failed", track_id)
            self._separation_failed[track_id] = time.monotonic()
            return False
        self._separation_failed.pop(track_id, None)
        return done

    def separate_waiting(self) -> bool:
        """Redo one track's waiting separation (left by a process that stopped between a
        run's commit and its separation); False when none waits. A track whose separation
        failed is retried after ``SEPARATION_RETRY_S``."""
        with self.ctx.db.session() as s:
            waiting = tracks_pending_separation(s)
        now = time.monotonic()
        for track_id in waiting:
            failed_at = self._separation_failed.get(track_id)
            if failed_at is None or now - failed_at > SEPARATION_RETRY_S:
                return self.separate_track(track_id)
        return False

    def _owned(self, run_id: int) -> Update:
        """An UPDATE of run ``run_id`` while this worker still owns its processing."""
        return update(Run).where(
            Run.id == run_id, Run.claimed_by == self.id, Run.status == "processing"
        )

    def _fail(self, s: Session, run_id: int, detail: dict[str, Any]) -> None:
        # A run that had a result (reprocessed after a vehicle edit), or whose result the
        # vehicle made implausible, keeps its log: restoring the vehicle must bring it back.
        had_result = s.scalar(select(Run.vehicle_version).where(Run.id == run_id)) is not None
        failed = _rowcount(
            s,
            update(Run)
            .where(Run.id == run_id, Run.claimed_by == self.id, Run.status == "processing")
            .values(status="failed", stage=None, error=detail, processed_at=utcnow()),
        )
        if failed == 1 and not had_result and detail.get("kind") != ImplausibleResult.__name__:
            s.execute(delete(RunInput).where(RunInput.run_id == run_id))
        s.commit()
