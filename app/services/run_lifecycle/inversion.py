"""Inverting a run's log: in the request (short logs), started early beside the storing of a
queued run's input, or by the worker that claimed the run.

Every path goes through :func:`app.services.run_lifecycle.processing.invert` under a processing slot
(``AppContext.slots``); this module only chooses the log, the set-up and the slot.
"""

from __future__ import annotations

from concurrent.futures import Future
from dataclasses import dataclass

from app.db.models import Run
from app.services.context import AppContext
from app.services.errors import Invalid
from app.services.run_lifecycle.handover import Handed
from app.services.run_lifecycle.logs import unpack_log
from app.services.run_lifecycle.processing import Processed, invert, start_inversion
from app.services.vehicles.loads import loaded_vehicle
from engine.errors import EngineError
from engine.setup import PreparedRun, RunSetup, prepare_run
from engine.track import TrackParams
from engine.vehicle_kinds import vehicle_from_dict


def invert_now(ctx: AppContext, prepared: PreparedRun) -> Processed:
    """Invert a submission's prepared log in the request (waits for a slot); the engine's
    objections as :class:`~app.services.errors.Invalid` (nothing is stored then)."""
    with ctx.slots:
        try:
            return invert(prepared, ctx.settings.processing_budget_s)
        except EngineError as exc:
            raise Invalid.from_engine(exc) from None


def start_early(ctx: AppContext, prepared: PreparedRun) -> Future[Processed] | None:
    """Start a queued submission's inversion now, for this process's worker to take (None
    when no slot is free: the worker inverts it after claiming the run); its long level is
    left for after the run is done, as the worker's own inversion leaves it."""
    return start_inversion(
        ctx.slots, prepared, ctx.settings.processing_budget_s, long_level_at="later"
    )


@dataclass
class ClaimedRun:
    """A claimed run's set-up and its log: handed over (prepared) by this process's request,
    else the stored (packed) input, freed once unpacked."""

    run_id: int
    setup: RunSetup
    vehicle_version: int
    vehicle_id: int
    handed: Handed | None
    packed: bytes | None

    @classmethod
    def of(cls, run: Run, handed: Handed | None, packed: bytes | None) -> ClaimedRun:
        """The set-up of ``run`` as stored now (the vehicle's current version, its load)."""
        vehicle = loaded_vehicle(
            vehicle_from_dict(run.vehicle.params_dict()), run.payload_kg,
            run.static_wheel_load_n,
        )  # fmt: skip
        track = TrackParams.from_dict(run.track.params_dict())
        setup = RunSetup(run.start_chainage_m, run.direction, vehicle, track)
        return cls(run.id, setup, run.vehicle.version, run.vehicle_id, handed, packed)

    def prepared(self) -> PreparedRun:
        """The log prepared for this set-up: the request's (prepared again only when the
        set-up changed since, e.g. a new vehicle version), else the stored input's, dropped
        here so that only the unpacked log stays in memory."""
        if self.handed is not None:
            return self.handed.prepared.with_setup(self.setup)
        packed, self.packed = self.packed, None
        assert packed is not None
        return prepare_run(unpack_log(packed), self.setup)


def invert_claimed(ctx: AppContext, claimed: ClaimedRun) -> Processed:
    """The claimed run's inversion: the one its request started, when it is of the same
    set-up, else a new one under a slot; both leave the long level for after the run is
    done (``Processed.later``)."""
    started = None if claimed.handed is None else claimed.handed.started_for(claimed.setup)
    if started is not None:
        # The request's inversion (holding its own slot); a vehicle version or start changed
        # since inverts again.
        return started.result()
    with ctx.slots:
        return invert(claimed.prepared(), ctx.settings.processing_budget_s, long_level_at="later")
