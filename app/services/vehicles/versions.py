"""Vehicles and their parameter versions; reprocessing a vehicle's runs in place.

A vehicle's parameters are versioned: registration makes version 1, every manual edit or
applied calibration the next one (old versions are kept, with who or what made them). A new
version queues every stored run of the vehicle for reprocessing with it: same run ids, the
background worker inverts the stored log again, and each run records the version its results
were computed with (``Run.vehicle_version``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from sqlalchemy import delete, func, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db.models import Run, RunInput, SoftSpot, Vehicle, VehicleVersion
from app.services.errors import Conflict, Invalid, NotFound
from app.services.storage.profiles import delete_profile
from app.services.track.integrate import remove_run_from_track
from engine.errors import ParameterError
from engine.vehicle_kinds import Vehicle as EngineVehicle
from engine.vehicle_kinds import vehicle_from_dict
from engine.vehicle_plausibility import check_vehicle, implausibilities, vehicle_quantities

T = TypeVar("T")


def checked_params(params: dict[str, Any], field: str = "params") -> EngineVehicle:
    """The engine's vehicle (of the mapping's ``kind``, default the half car) from a
    parameter mapping, plausible as a whole (:func:`engine.vehicle_plausibility.check_vehicle`);
    Invalid naming the parameter, or the derived quantity out of range, otherwise."""
    try:
        vp = vehicle_from_dict(params)
        check_vehicle(vp, vp.kind, field=field)
    except ParameterError as exc:
        # a request's params object: name the parameter in it; another field (load_kg) as is
        if field == "params":
            raise _invalid_params(exc, field) from None
        raise Invalid.from_engine(exc, field=field) from None
    return vp


def _invalid_params(exc: ParameterError, field: str) -> Invalid:
    """Invalid naming the request field, and the parameter inside it when the engine names
    one (``params.ks1``), as a schema error names a nested field."""
    err = Invalid.from_engine(exc, field=field)
    named = err.facts.get("field")
    if named and named != field and not str(named).startswith(f"{field}."):
        err.facts["field"] = f"{field}.{named}"
    return err


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


def reprocessing_left(session: Session, track_id: int) -> int:
    """Runs of the track being processed again after a vehicle edit (they had a result)."""
    return int(
        session.scalar(
            select(func.count())
            .select_from(Run)
            .where(
                Run.track_id == track_id,
                Run.status == "processing",
                Run.vehicle_version.is_not(None),
            )
        )
        or 0
    )


def require_settled(session: Session, track_id: int, what: str) -> None:
    """:class:`Conflict` (``status`` "updating") while a vehicle edit reprocesses runs of
    the track: its aggregate, register and separation are then rebuilt run by run, and a
    reader would see a mixture of old and new results (a defect's level flipping)."""
    left = reprocessing_left(session, track_id)
    if left:
        raise Conflict(
            f"the track is updating: a vehicle edit is reprocessing its runs ({left} left); "
            f"its {what} is answered once the new state is complete, read again in a few "
            "seconds",
            status="updating",
            runs_left=left,
        )


def read_settled(session: Session, track_id: int, what: str, read: Callable[[], T]) -> T:
    """``read()`` of a track's derived data, refused (:func:`require_settled`) when a
    reprocessing was under way before or after it: never a half-rebuilt state."""
    require_settled(session, track_id, what)
    out = read()
    require_settled(session, track_id, what)
    return out


def edit_vehicle(
    session: Session,
    vehicle: Vehicle,
    changes: dict[str, Any],
    *,
    created_by: str | None = None,
    note: str | None = None,
) -> tuple[int, int]:
    """A manual edit of some parameters: a new version, runs reprocessed. Commits and
    refreshes ``vehicle``.

    Returns ``(version, runs queued)``; Invalid when nothing changes or a value is wrong.
    """
    if not changes:
        raise Invalid("give at least one parameter to change", field="params")
    params = checked_params({**vehicle.params_dict(), **changes})
    if params.to_dict() == vehicle.params_dict():
        raise Invalid("the parameters given are the vehicle's current ones", field="params")
    out = new_version(session, vehicle, params, source="manual", created_by=created_by, note=note)
    session.commit()
    session.refresh(vehicle)
    return out


def runs_to_reprocess(session: Session, vehicle_id: int) -> int:
    """How many runs a new version of the vehicle would reprocess (those with a stored log)."""
    return int(
        session.scalar(
            select(func.count())
            .select_from(Run)
            .join(RunInput, RunInput.run_id == Run.id)
            .where(Run.vehicle_id == vehicle_id)
        )
        or 0
    )


@dataclass(frozen=True)
class EditPreview:
    """What an edit would do, stored nothing (``PATCH ...?dry_run=true``)."""

    params: dict[str, float]
    """The vehicle's parameters after the edit, SI."""
    changes: dict[str, tuple[float, float]]
    """Each parameter that changes: (now, after)."""
    version: int
    """The version the edit would make."""
    runs_reprocessed: int
    plausible: bool
    problems: list[str]
    """Why the parameters are not a plausible vehicle (empty when they are)."""
    quantities: dict[str, float]
    """The derived quantities judged (engine.vehicle_plausibility.RANGES)."""


def preview_edit(session: Session, vehicle: Vehicle, changes: dict[str, Any]) -> EditPreview:
    """What :func:`edit_vehicle` would do with ``changes``; nothing is stored.

    A parameter out of its own range is still Invalid (there is no vehicle to judge); a
    vehicle that is implausible as a whole is answered with ``plausible`` False and why.
    """
    if not changes:
        raise Invalid("give at least one parameter to change", field="params")
    try:
        vp = vehicle_from_dict({**vehicle.params_dict(), **changes})
    except ParameterError as exc:
        raise _invalid_params(exc, "params") from None
    now, after = vehicle.params_dict(), vp.to_dict()
    found = implausibilities(vp, vp.kind)
    return EditPreview(
        params=after,
        changes={k: (now[k], v) for k, v in after.items() if now.get(k) != v},
        version=vehicle.version + 1,
        runs_reprocessed=runs_to_reprocess(session, vehicle.id),
        plausible=not found,
        problems=[f.message for f in found],
        quantities=vehicle_quantities(vp, vp.kind),
    )


def restore_version(
    session: Session,
    vehicle: Vehicle,
    version: int,
    *,
    created_by: str | None = None,
    note: str | None = None,
) -> tuple[int, int]:
    """Make an earlier version's parameters the vehicle's next version (its runs are
    reprocessed with them). Commits (``vehicle`` refreshed); returns ``(version, runs queued)``.

    What the versions in between produced does not matter: their results are replaced.
    Restoring the parameters the vehicle has now changes nothing (``(current, 0)``).

    Raises
    ------
    NotFound
        No such version of this vehicle.
    Invalid
        The version's parameters are not a plausible vehicle (one stored before the checks).
    """
    row = session.scalar(
        select(VehicleVersion).where(
            VehicleVersion.vehicle_id == vehicle.id, VehicleVersion.version == version
        )
    )
    if row is None:
        raise NotFound(
            f"vehicle {vehicle.name!r} has no version {version} (it is at version "
            f"{vehicle.version})",
            field="version",
        )
    params = checked_params(dict(row.params))
    if params.to_dict() == vehicle.params_dict():
        return vehicle.version, 0
    out = new_version(
        session, vehicle, params, source="restore", created_by=created_by,
        note=note or f"restored version {version}",
    )  # fmt: skip
    session.commit()
    session.refresh(vehicle)
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
