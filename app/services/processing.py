"""Running the engine on a log and storing what it gives, in one transaction per run."""

from __future__ import annotations

import math
import threading
import time
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from app.db.base import utcnow
from app.db.models import Run, SoftSpot
from engine.budget import TimeBudget
from engine.pipeline import RunCheck, process_run
from engine.results import ProcessResult
from engine.runlog import RunLog
from engine.track import TrackParams
from engine.vehicle_kinds import Vehicle as EngineVehicle

from .integrate import Separation, add_run_to_track
from .profiles import fuse_axles, insert_profile


@dataclass(frozen=True)
class Processed:
    """An engine result and how long it took, s."""

    result: ProcessResult
    seconds: float


def invert(
    log: RunLog,
    *,
    start_chainage_m: float | None,
    direction: str,
    vehicle: EngineVehicle,
    track: TrackParams,
    budget_s: float | None = None,
    checked: RunCheck | None = None,
) -> Processed:
    """Invert and detect (engine pipeline); raises the engine's errors unchanged, and
    :class:`~engine.errors.BudgetExceeded` past ``budget_s`` of wall time (s;
    ``TRACKPROFILE_PROCESSING_BUDGET_S``). ``checked``: the submission's pre-flight of this
    log with these parameters (not repeated; see :func:`engine.pipeline.process_run`)."""
    t0 = time.perf_counter()
    budget = (
        TimeBudget(budget_s, "processing", "TRACKPROFILE_PROCESSING_BUDGET_S")
        if budget_s is not None
        else None
    )
    result = process_run(
        log, start_chainage_m=start_chainage_m, direction=direction, vehicle=vehicle,
        track=track, budget=budget, checked=checked,
    )  # fmt: skip
    return Processed(result, time.perf_counter() - t0)


@dataclass(frozen=True)
class StartedInversion:
    """An inversion started before its run was claimed (:func:`start_inversion`), with the
    inputs it runs with: the worker that claims the run takes its result when its own inputs
    are the same, and inverts again otherwise."""

    future: Future[Processed]
    inputs: tuple[float | None, str, EngineVehicle, TrackParams]
    """``(start_chainage_m, direction, vehicle, track)``."""

    def matches(
        self, start_chainage_m: float | None, direction: str, vehicle: EngineVehicle,
        track: TrackParams,
    ) -> bool:  # fmt: skip
        """Whether it inverts the log with these inputs."""
        return self.inputs == (start_chainage_m, direction, vehicle, track)

    def result(self) -> Processed:
        """Its result once done (waits); raises what the inversion raised."""
        return self.future.result()


def start_inversion(
    slots: threading.BoundedSemaphore,
    log: RunLog,
    *,
    start_chainage_m: float | None,
    direction: str,
    vehicle: EngineVehicle,
    track: TrackParams,
    budget_s: float | None,
    checked: RunCheck,
) -> StartedInversion | None:
    """Invert a queued run's log on a thread of its own now, while its input is still being
    stored, instead of after a worker has claimed it; None when no processing slot is free
    (the worker inverts it then, as any queued run).

    The slot (``AppContext.slots``: the memory cap on inversions at once) is held until the
    inversion ends. Crash safety is the queue's: the run is stored before the client is
    answered, and a process that dies with the inversion in hand leaves it to another worker.
    """
    if not slots.acquire(blocking=False):
        return None
    future: Future[Processed] = Future()

    def run() -> None:
        try:
            if future.set_running_or_notify_cancel():
                future.set_result(
                    invert(
                        log,
                        start_chainage_m=start_chainage_m,
                        direction=direction,
                        vehicle=vehicle,
                        track=track,
                        budget_s=budget_s,
                        checked=checked,
                    )
                )
        except BaseException as exc:  # handed to whoever takes the result
            future.set_exception(exc)
        finally:
            slots.release()

    threading.Thread(target=run, name="early-inversion", daemon=True).start()
    return StartedInversion(future, (start_chainage_m, direction, vehicle, track))


def finite_or_none(value: Any) -> float | None:
    """A JSON-safe number: NaN and infinities become None."""
    try:
        f = float(value)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


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
    (``app.services.integrate``), in the same transaction; the track's geometry/stiffness
    separation there is redone in it too, or marked for after it (``separation="later"``:
    the worker's, :func:`~app.services.integrate.separate_pending`).
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
    # Where the rail is not smooth at the noise level geometry could have made these dips:
    # they are kept by depth only, no stiffness-loss figure is stored for them.
    check = res.geometry_check
    valid = True if check is None else bool(check.smooth)
    for spot in res.soft_spots:
        session.add(
            SoftSpot(
                run_id=run.id,
                start_m=float(spot.start_m),
                end_m=float(spot.end_m),
                peak_m=float(spot.peak_m),
                depth_mm=float(spot.depth_mm),
                stiffness_loss_pct=finite_or_none(spot.stiffness_loss_pct) if valid else None,
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
    run.mean_wheel_force_n = float(under_level.mean()) if under_level.size else None
    run.single_pass_valid = None if check is None else valid
    run.status = "done"
    run.stage = None
    run.error = None
    run.processed_at = utcnow()
    run.vehicle_version = vehicle_version
    add_run_to_track(
        session, run, res.chainage_m, res.level_mm, force if under_level.size else None,
        separation=separation,
    )  # fmt: skip
