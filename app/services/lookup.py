"""Tracks and vehicles found by id or name, and made when they are new: the one lookup and
creation behind every route (``/tracks/{track}``, ``/vehicles/{vehicle}``, ``POST /tracks``,
``POST /vehicles``) and behind run intake (uploads, JSON arrays, simulations).

Two ways to name a row, two answers when there is none: a path parameter (``ref``: the id in
ASCII digits, or the name) that matches nothing is :class:`NotFound`; a field of a submission
(``track_id``, ``vehicle``) that does is :class:`Invalid`, naming the field.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db.models import Track, Vehicle
from app.schemas.common import as_id, url_name_problem
from app.services.errors import Conflict, Invalid, NotFound
from app.services.vehicles.versions import create_vehicle
from engine.track import TrackParams
from engine.vehicle_kinds import KIND_PRESETS

DEFAULT_VEHICLE = "table1"
"""The vehicle of a submission that names none (the paper's Table 1 vehicle)."""

TRACK_DEFAULTS: dict[str, Any] = {"rail": "UIC60", **TrackParams().to_dict()}
"""The columns of a new track nobody described: UIC60 on 80 kN/mm supports."""

Row = TypeVar("Row", Track, Vehicle)


def _named(session: Session, model: type[Row], name: str | None) -> Row | None:
    return session.scalar(select(model).where(model.name == name))


def _page(session: Session, model: type[Row], offset: int, limit: int) -> tuple[list[Row], int]:
    count = session.scalar(select(func.count()).select_from(model)) or 0
    rows = session.scalars(select(model).order_by(model.name).offset(offset).limit(limit)).all()
    return list(rows), int(count)


def _by_ref(session: Session, model: type[Row], ref: str, field: str) -> Row:
    try:
        row_id = as_id(ref)
    except ValueError as exc:
        raise Invalid(f"{field} {ref[:30]}...: {exc}", field=field, kind="OutOfRange") from None
    row = session.get(model, row_id) if row_id is not None else None
    if row is None:
        row = _named(session, model, ref)
    if row is None:
        raise NotFound(f"{field} {ref!r} not found (give its id or its name)", field=field)
    return row


def _numbered(session: Session, model: type[Row], row_id: int, field: str) -> Row:
    row = session.get(model, row_id)
    if row is None:
        raise Invalid(f"{field} {row_id} does not exist", field=field)
    return row


def get_track(session: Session, ref: str) -> Track:
    """The track whose id (ASCII digits) or name is ``ref``; NotFound when none."""
    return _by_ref(session, Track, ref, "track")


def get_vehicle(session: Session, ref: str) -> Vehicle:
    """The vehicle whose id (ASCII digits) or name is ``ref``; NotFound when none."""
    return _by_ref(session, Vehicle, ref, "vehicle")


def list_tracks(session: Session, offset: int, limit: int) -> tuple[list[Track], int]:
    """A page of tracks by name, and how many tracks there are."""
    return _page(session, Track, offset, limit)


def list_vehicles(session: Session, offset: int, limit: int) -> tuple[list[Vehicle], int]:
    """A page of vehicles by name, and how many vehicles there are."""
    return _page(session, Vehicle, offset, limit)


def resolve_track(session: Session, name: str | None, track_id: int | None) -> Track | None:
    """The track numbered (Invalid when unknown) or named (None: a new track of that name)."""
    if track_id is not None:
        return _numbered(session, Track, track_id, "track_id")
    return _named(session, Track, name)


def resolve_vehicle(session: Session, name: str | None, vehicle_id: int | None) -> Vehicle:
    """The vehicle numbered or named (default: the Table 1 vehicle); a preset's name is the
    preset, stored on first use; Invalid when unknown."""
    if vehicle_id is not None:
        return _numbered(session, Vehicle, vehicle_id, "vehicle_id")
    wanted = name or DEFAULT_VEHICLE
    v = _named(session, Vehicle, wanted)
    if v is None and wanted in KIND_PRESETS:
        v = vehicle_from_preset(session, wanted)
    if v is None:
        # Only the engine's presets are named: the stored vehicles are listed by
        # GET /api/v1/vehicles to those who may read them, not in every error.
        raise Invalid(
            f"vehicle {wanted!r} does not exist; the presets are {', '.join(sorted(KIND_PRESETS))} "
            "(the stored vehicles: GET /api/v1/vehicles; a new one: POST /api/v1/vehicles)",
            field="vehicle",
        )
    return v


def preset_params(preset: str, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The parameters of the engine's vehicle preset ``preset`` with ``overrides`` over them;
    Invalid naming ``preset`` when there is no such preset."""
    if preset not in KIND_PRESETS:
        raise Invalid(
            f"unknown vehicle preset {preset!r}; expected one of {', '.join(sorted(KIND_PRESETS))}",
            field="preset",
        )
    return KIND_PRESETS[preset].to_dict() | dict(overrides or {})


def vehicle_from_preset(session: Session, preset: str, name: str | None = None) -> Vehicle:
    """Register the engine's vehicle preset ``preset`` as a vehicle (named after it by
    default, version 1). Commits; a concurrent first use of the same preset loses the race on
    the unique name and finds the other's row."""
    wanted = name or preset
    try:
        return create_vehicle(
            session, wanted, f"Engine vehicle preset {preset!r}", preset_params(preset)
        )
    except Conflict:
        found = _named(session, Vehicle, wanted)
        assert found is not None
        return found


def check_new_track_name(name: str | None) -> None:
    """Invalid (field ``track``) when a new track's name could not address it in URLs
    (``/api/v1/tracks/{track}``); tracks that exist are found by their name whatever it is."""
    problem = url_name_problem(name or "")
    if problem is not None:
        raise Invalid(f"track name {name!r} {problem}", field="track")


def track_params(columns: Mapping[str, Any]) -> dict[str, Any]:
    """The engine's track parameters among a track's columns."""
    return {k: v for k, v in columns.items() if k in TrackParams.__dataclass_fields__}


def new_track_columns(given: Mapping[str, Any]) -> dict[str, Any]:
    """The columns of a new track: the given properties over :data:`TRACK_DEFAULTS`, checked
    by the engine (a ParameterError names the field)."""
    columns = TRACK_DEFAULTS | dict(given)
    TrackParams.from_dict(track_params(columns))
    return columns


def create_track(session: Session, name: str, given: Mapping[str, Any]) -> Track:
    """Register a track named ``name`` with the columns ``given`` (description, rail, the
    engine's parameters; the rest default); Conflict when the name is taken. Commits."""
    check_new_track_name(name)
    columns = new_track_columns(given)
    if _named(session, Track, name) is not None:
        raise Conflict(f"a track named {name!r} already exists", field="name")
    track = Track(name=name, **columns)
    session.add(track)
    try:
        session.commit()
    except IntegrityError:
        session.rollback()
        raise Conflict(f"a track named {name!r} already exists", field="name") from None
    return track
