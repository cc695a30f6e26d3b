"""Inverting a run's log: in the request (short logs), started early beside the storing of a
queued run's input, or by the worker that claimed the run.

Every path goes through :func:`app.services.processing.invert` under a processing slot
(``AppContext.slots``); this module only chooses the log, the set-up and the slot.
"""

from __future__ import annotations

from dataclasses import dataclass

from app.db.models import Run
from engine.errors import EngineError
from engine.pipeline import RunCheck
from engine.runlog import RunLog
from engine.track import TrackParams
from engine.vehicle_kinds import Vehicle as EngineVehicle
from engine.vehicle_kinds import vehicle_from_dict

from ..context import AppContext
from ..errors import Invalid
from ..handover import Handed
from ..loads import loaded_vehicle
from ..logs import unpack_log
from ..processing import Processed, StartedInversion, invert, start_inversion
from .intake import Submission


def invert_now(
    ctx: AppContext, sub: Submission, vehicle: EngineVehicle, track: TrackParams, check: RunCheck
) -> Processed:
    """Invert a submission's log in the request (waits for a slot); the engine's objections
    as :class:`~app.services.errors.Invalid` (nothing is stored then)."""
    with ctx.slots:
        try:
            return invert(
                sub.log, start_chainage_m=sub.start_chainage_m, direction=sub.direction,
                vehicle=vehicle, track=track, budget_s=ctx.settings.processing_budget_s,
                checked=check,
            )  # fmt: skip
        except EngineError as exc:
            raise Invalid.from_engine(exc) from None


def start_early(
    ctx: AppContext, sub: Submission, vehicle: EngineVehicle, track: TrackParams, check: RunCheck
) -> StartedInversion | None:
    """Start a queued submission's inversion now, for this process's worker to take (None
    when no slot is free: the worker inverts it after claiming the run)."""
    return start_inversion(
        ctx.slots, sub.log, start_chainage_m=sub.start_chainage_m, direction=sub.direction,
        vehicle=vehicle, track=track, budget_s=ctx.settings.processing_budget_s, checked=check,
    )  # fmt: skip


@dataclass
class ClaimedRun:
    """A claimed run's set-up and its log: handed over by this process's request, else the
    stored (packed) input, freed once unpacked."""

    run_id: int
    vehicle: EngineVehicle
    vehicle_version: int
    vehicle_id: int
    track: TrackParams
    start_chainage_m: float | None
    direction: str
    handed: Handed | None
    packed: bytes | None

    @classmethod
    def of(cls, run: Run, handed: Handed | None, packed: bytes | None) -> ClaimedRun:
        """The set-up of ``run`` as stored now (the vehicle's current version, its load)."""
        vehicle = loaded_vehicle(
            vehicle_from_dict(run.vehicle.params_dict()), run.payload_kg,
            run.static_wheel_load_n,
        )  # fmt: skip
        return cls(
            run.id, vehicle, run.vehicle.version, run.vehicle_id,
            TrackParams.from_dict(run.track.params_dict()), run.start_chainage_m, run.direction,
            handed, packed,
        )  # fmt: skip

    def take_log(self) -> tuple[RunLog, RunCheck | None]:
        """The log and its pre-flight check (None: not checked for this set-up yet); the
        stored input is dropped here, so that only the unpacked log stays in memory."""
        if self.handed is not None:
            # Checked by the submission for these parameters (a changed vehicle version
            # or start makes process_run check again).
            return self.handed.log, self.handed.check
        packed, self.packed = self.packed, None
        assert packed is not None
        return unpack_log(packed), None


def invert_claimed(ctx: AppContext, claimed: ClaimedRun) -> Processed:
    """The claimed run's inversion: the one its request started, when it inverts the same
    log with the same set-up, else a new one under a slot."""
    started = None if claimed.handed is None else claimed.handed.inversion
    setup = (claimed.start_chainage_m, claimed.direction, claimed.vehicle, claimed.track)
    if started is not None and started.matches(*setup):
        # The request's inversion (holding its own slot) of the same inputs; a vehicle
        # version or start changed since inverts again.
        return started.result()
    with ctx.slots:
        runlog, checked = claimed.take_log()
        return invert(
            runlog, start_chainage_m=claimed.start_chainage_m, direction=claimed.direction,
            vehicle=claimed.vehicle, track=claimed.track,
            budget_s=ctx.settings.processing_budget_s, checked=checked,
        )  # fmt: skip
