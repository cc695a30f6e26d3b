"""Vehicles: ``GET/POST /api/v1/vehicles``, ``GET /api/v1/vehicles/{vehicle}`` (id or name)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError

from app.api.convert import vehicle_public
from app.api.deps import SessionDep
from app.db.models import Vehicle
from app.schemas.vehicles import VehicleCreate, VehiclePublic, VehiclesPublic
from app.services.errors import Conflict, Invalid
from engine.errors import ParameterError
from engine.vehicle import VehicleParams

from .lookup import get_vehicle

router = APIRouter(prefix="/vehicles", tags=["vehicles"])


@router.get("", response_model=VehiclesPublic)
def list_vehicles(
    session: SessionDep,
    offset: Annotated[int, Query(ge=0)] = 0,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
) -> VehiclesPublic:
    """Vehicles by name (``table1``, the paper's Table 1 vehicle, always exists)."""
    count = session.scalar(select(func.count()).select_from(Vehicle)) or 0
    rows = session.scalars(select(Vehicle).order_by(Vehicle.name).offset(offset).limit(limit)).all()
    return VehiclesPublic(data=[vehicle_public(v) for v in rows], count=count)


@router.post("", response_model=VehiclePublic, status_code=201)
def create_vehicle(session: SessionDep, body: VehicleCreate) -> VehiclePublic:
    """Create a vehicle from its half-car parameters (SI); 409 if the name is taken."""
    params = body.params.model_dump()
    try:
        VehicleParams.from_dict(params)
    except ParameterError as exc:
        raise Invalid.from_engine(exc, field="params") from None
    if session.scalar(select(Vehicle.id).where(Vehicle.name == body.name)) is not None:
        raise Conflict(f"a vehicle named {body.name!r} already exists", field="name")
    vehicle = Vehicle(name=body.name, description=body.description, **params)
    session.add(vehicle)
    try:
        session.commit()
    except IntegrityError:
        session.rollback()
        raise Conflict(f"a vehicle named {body.name!r} already exists", field="name") from None
    return vehicle_public(vehicle)


@router.get("/{vehicle}", response_model=VehiclePublic)
def read_vehicle(session: SessionDep, vehicle: str) -> VehiclePublic:
    """One vehicle, by id or name."""
    return vehicle_public(get_vehicle(session, vehicle))
