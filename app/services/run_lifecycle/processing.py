"""Running the engine on a log and storing what it gives, in one transaction per run."""

from __future__ import annotations

import threading
import time
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from sqlalchemy.orm import Session

from app.db.base import utcnow
from app.db.models import Run, SoftSpot
from app.services.storage.profiles import finite_or_none, insert_profile
from app.services.track.integrate import Separation, add_run_to_track
from engine.budget import TimeBudget
from engine.pipeline import PreparedRun, fuse_axles, process_run
from engine.results import ProcessResult
from engine.track_quality import long_level
from engine.vehicle_kinds import per_wheel

LongLevelAt = Literal["now", "later"]
"""When a run's long level (:func:`engine.track_quality.long_level`) is inverted: with its
result, or after the run is answered done (the worker's next step,
:mod:`app.services.run_lifecycle.jobs.long_level`): it costs about as much again as the run's
own inversion, and only D2 needs it."""


@dataclass(frozen=True)
class Processed:
    """An engine result, the run's long level on its grid (mm; None: too short for its band,
    or left for later) and how long they took, s."""

    result: ProcessResult
    seconds: float
    wheel_offsets_m: tuple[float, ...] = (0.0,)
    """The wheels of a measured point about it, m (the vehicle's): they share its force."""
    long_level_mm: NDArray[np.float64] | None = None
    later: PreparedRun | None = None
    """The run whose long level is left for after it is stored (``long_level_at="later"``);
    None when it was inverted with the result."""


def invert(
    run: PreparedRun, budget_s: float | None = None, *, long_level_at: LongLevelAt = "now"
) -> Processed:
    """Invert and detect (engine pipeline), then (``long_level_at="now"``) the long level D2
    is filtered from (:func:`engine.track_quality.long_level`); raises the engine's errors
    unchanged, and :class:`~engine.errors.BudgetExceeded` past ``budget_s`` of wall time (s;
    ``TRACKPROFILE_PROCESSING_BUDGET_S``)."""
    t0 = time.perf_counter()
    budget = (
        TimeBudget(budget_s, "processing", "TRACKPROFILE_PROCESSING_BUDGET_S")
        if budget_s is not None
        else None
    )
    result = process_run(run, budget=budget)
    wheels = tuple(run.setup.vehicle.axle_wheel_offsets_m[0])
    if long_level_at == "later":
        return Processed(result, time.perf_counter() - t0, wheels, later=run)
    long = long_level(run)
    if budget is not None:
        budget.check("the long level")
    return Processed(result, time.perf_counter() - t0, wheels, long)


def start_inversion(
    slots: threading.BoundedSemaphore,
    run: PreparedRun,
    budget_s: float | None,
    *,
    long_level_at: LongLevelAt = "now",
) -> Future[Processed] | None:
    """Invert a queued run now, on a thread of its own, while its input is still being
    stored, instead of after a worker has claimed it; None when no processing slot is free
    (the worker inverts it then, as any queued run).

    The slot (``AppContext.slots``: the memory cap on inversions at once) is held until the
    inversion ends. Crash safety is the queue's: the run is stored before the client is
    answered, and a process that dies with the inversion in hand leaves it to another worker.
    """
    if not slots.acquire(blocking=False):
        return None
    future: Future[Processed] = Future()

    def work() -> None:
        try:
            if future.set_running_or_notify_cancel():
                future.set_result(invert(run, budget_s, long_level_at=long_level_at))
        except BaseException as exc:  # handed to whoever takes the result
            future.set_exception(exc)
        finally:
            slots.release()

    threading.Thread(target=work, name="early-inversion", daemon=True).start()
    return future


def mean_wheel_load(processed: Processed) -> float | None:
    """The mean force per wheel under a run's profile, N (None without one): the measured
    points' fused force shared by each point's wheels, so that runs of one wheel load are one
    load whatever their vehicle kind."""
    res = processed.result
    if res.front_force_n is None or res.rear_force_n is None:
        return None
    force = fuse_axles(res.front_force_n, res.rear_force_n)
    under_level = force[np.isfinite(res.level_mm) & np.isfinite(force)]
    if not under_level.size:
        return None
    return per_wheel(float(under_level.mean()), processed.wheel_offsets_m)


def store_result(
    session: Session,
    run: Run,
    processed: Processed,
    vehicle_version: int | None,
    *,
    separation: Separation = "now",
) -> None:
    """Write a run's profile and soft spots and mark it done (caller commits).

    ``vehicle_version`` is the vehicle parameter version the result was computed with. The
    run's log stays stored: a new vehicle version reprocesses it, calibration reads it.

    Chainage in m, levels in mm; the run's chainage extent is where the fused level exists.
    The run is then aligned to its track and merged into the track's aggregated profile
    (``app.services.track.integrate``), in the same transaction; the track's geometry/stiffness
    separation there is redone in it too, or marked for after it (``separation="later"``:
    the worker's, :func:`~app.services.track.integrate.separate_pending`). A long level left
    for later (``processed.later``) is marked pending (:func:`~app.services.track.integrate.
    store_long_level` stores it).
    """
    res = processed.result
    no_force = np.full(res.chainage_m.shape, np.nan)
    front_force = no_force if res.front_force_n is None else res.front_force_n
    rear_force = no_force if res.rear_force_n is None else res.rear_force_n
    insert_profile(
        session,
        run.id,
        res.chainage_m,
        res.front_level_mm,
        res.rear_level_mm,
        res.baseline_mm,
        front_force,
        rear_force,
    )
    # The engine gives no stiffness-loss figure where the rail is rough (NaN, stored NULL).
    check = res.geometry_check
    for spot in res.soft_spots:
        session.add(
            SoftSpot(
                run_id=run.id,
                start_m=float(spot.start_m),
                end_m=float(spot.end_m),
                peak_m=float(spot.peak_m),
                depth_mm=float(spot.depth_mm),
                stiffness_loss_pct=finite_or_none(spot.stiffness_loss_pct),
            )
        )
    covered = res.chainage_m[np.isfinite(res.level_mm)]
    run.chainage_min_m = float(covered[0]) if covered.size else None
    run.chainage_max_m = float(covered[-1]) if covered.size else None
    run.quality = {k: finite_or_none(v) for k, v in res.quality.to_dict().items()}
    run.detection_limit = None if res.detection_limit is None else res.detection_limit.to_dict()
    run.method = res.method
    run.n_soft_spots = len(res.soft_spots)
    run.processing_s = processed.seconds
    force = fuse_axles(front_force, rear_force)
    under_level = force[np.isfinite(res.level_mm) & np.isfinite(force)]
    run.mean_wheel_force_n = mean_wheel_load(processed)
    run.single_pass_valid = None if check is None else bool(check.smooth)
    run.status = "done"
    run.stage = None
    run.error = None
    run.processed_at = utcnow()
    run.vehicle_version = vehicle_version
    run.long_level_pending = processed.later is not None
    add_run_to_track(
        session, run, res.chainage_m, res.level_mm, force if under_level.size else None,
        separation=separation, long_mm=processed.long_level_mm,
    )  # fmt: skip
