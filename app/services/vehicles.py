"""Vehicles and their parameter versions; reprocessing a vehicle's runs in place.

A vehicle's parameters are versioned: registration makes version 1, every manual edit or
applied calibration the next one (old versions are kept, with who or what made them). A new
version queues every stored run of the vehicle for reprocessing with it: same run ids, the
background worker inverts the stored log again, and each run records the version its results
were computed with (``Run.vehicle_version``).
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import delete, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db.models import Run, RunInput, SoftSpot, Vehicle, VehicleVersion
from engine.errors import ParameterError
from engine.vehicle_kinds import Vehicle as EngineVehicle
from engine.vehicle_kinds import vehicle_from_dict

from .errors import Conflict, Invalid
from .integrate import remove_run_from_track
from .profiles import delete_profile


def checked_params(params: dict[str, Any], field: str = "params") -> EngineVehicle:
    """The engine's vehicle (of the mapping's ``kind``, default the half car) from a
    parameter mapping; Invalid naming the parameter otherwise."""
    try:
        return vehicle_from_dict(params)
    except ParameterError as exc:
        raise Invalid.from_engine(exc, field=field) from None


def create_vehicle(
    session: Session,
    name: str,
    description: str | None,
    params: dict[str, Any],
    created_by: str | None = None,
) -> Vehicle:
    """Register a vehicle (version 1); Conflict when the name is taken. Commits."""
    vp = checked_params(params)
    if session.scalar(select(Vehicle.id).where(Vehicle.name == name)) is not None:
        raise Conflict(f"a vehicle named {name!r} already exists", field="name")
    vehicle = Vehicle(name=name, description=description, version=1)
    vehicle.set_params(vp)
    session.add(vehicle)
    try:
        session.flush()
        session.add(
            VehicleVersion(
                vehicle_id=vehicle.id, version=1, params=vp.to_dict(), source="created",
                created_by=created_by,
            )
        )  # fmt: skip
        session.commit()
    except IntegrityError:
        session.rollback()
        raise Conflict(f"a vehicle named {name!r} already exists", field="name") from None
    return vehicle


def new_version(
    session: Session,
    vehicle: Vehicle,
    params: EngineVehicle,
    *,
    source: str,
    created_by: str | None = None,
    calibration_id: int | None = None,
    note: str | None = None,
) -> tuple[int, int]:
    """Make ``params`` the vehicle's next version and queue its runs for reprocessing.

    The caller commits. Returns ``(version, runs queued)``.
    """
    # the row lock orders concurrent editors of one vehicle (version numbers stay unique)
    session.execute(select(Vehicle.id).where(Vehicle.id == vehicle.id).with_for_update())
    session.refresh(vehicle)
    version = vehicle.version + 1
    vehicle.set_params(params)
    vehicle.version = version
    session.add(
        VehicleVersion(
            vehicle_id=vehicle.id, version=version, params=params.to_dict(), source=source,
            created_by=created_by, calibration_id=calibration_id, note=note,
        )
    )  # fmt: skip
    session.flush()
    return version, reprocess_vehicle_runs(session, vehicle.id)


def reprocess_vehicle_runs(session: Session, vehicle_id: int) -> int:
    """Queue every run of the vehicle that has its log stored for processing again, in place.

    Results are removed (profile, soft spots, the run's share of its track's aggregate) and
    the run goes back to ``processing``/``queued``; a run a worker holds loses its claim, so
    that worker drops its (old-parameter) result. The caller commits; returns how many.
    """
    ids = session.scalars(
        select(Run.id)
        .join(RunInput, RunInput.run_id == Run.id)
        .where(Run.vehicle_id == vehicle_id)
        .order_by(Run.id)
    ).all()
    for run_id in ids:
        run = session.get(Run, run_id)
        assert run is not None
        remove_run_from_track(session, run)
        delete_profile(session, run_id)
        session.execute(delete(SoftSpot).where(SoftSpot.run_id == run_id))
    if ids:
        session.execute(
            update(Run)
            .where(Run.id.in_(ids))
            .values(
                status="processing", stage="queued", claimed_by=None, heartbeat_at=None,
                attempts=0, error=None, n_soft_spots=None, alignment_status=None,
                chainage_offset_m=0.0,
            )
        )  # fmt: skip
        session.expire_all()
    return len(ids)


def edit_vehicle(
    session: Session,
    vehicle: Vehicle,
    changes: dict[str, Any],
    *,
    created_by: str | None = None,
    note: str | None = None,
) -> tuple[int, int]:
    """A manual edit of some parameters: a new version, runs reprocessed. Commits.

    Returns ``(version, runs queued)``; Invalid when nothing changes or a value is wrong.
    """
    if not changes:
        raise Invalid("give at least one parameter to change", field="params")
    params = checked_params({**vehicle.params_dict(), **changes})
    if params.to_dict() == vehicle.params_dict():
        raise Invalid("the parameters given are the vehicle's current ones", field="params")
    out = new_version(session, vehicle, params, source="manual", created_by=created_by, note=note)
    session.commit()
    return out


def versions_of(session: Session, vehicle_id: int) -> list[VehicleVersion]:
    """The vehicle's parameter versions, newest first."""
    return list(
        session.scalars(
            select(VehicleVersion)
            .where(VehicleVersion.vehicle_id == vehicle_id)
            .order_by(VehicleVersion.version.desc())
        ).all()
    )
