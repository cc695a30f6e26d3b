"""Finding a track or vehicle by id or by name (path parameters accept both)."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Track, Vehicle
from app.schemas.common import as_id
from app.services.errors import Invalid, NotFound


def _id(ref: str, field: str) -> int | None:
    try:
        return as_id(ref)
    except ValueError as exc:
        raise Invalid(f"{field} {ref[:30]}...: {exc}", field=field, kind="OutOfRange") from None


def get_track(session: Session, ref: str) -> Track:
    """The track whose id (ASCII digits) or name is ``ref``; 404 when none."""
    track = session.get(Track, tid) if (tid := _id(ref, "track")) is not None else None
    if track is None:
        track = session.scalar(select(Track).where(Track.name == ref))
    if track is None:
        raise NotFound(f"track {ref!r} not found (give its id or its name)", field="track")
    return track


def get_vehicle(session: Session, ref: str) -> Vehicle:
    """The vehicle whose id (ASCII digits) or name is ``ref``; 404 when none."""
    vehicle = session.get(Vehicle, vid) if (vid := _id(ref, "vehicle")) is not None else None
    if vehicle is None:
        vehicle = session.scalar(select(Vehicle).where(Vehicle.name == ref))
    if vehicle is None:
        raise NotFound(f"vehicle {ref!r} not found (give its id or its name)", field="vehicle")
    return vehicle
