"""Vehicles: ``GET/POST /api/v1/vehicles``, ``GET/PATCH /api/v1/vehicles/{vehicle}`` (id or
name), parameter versions and restoring one, calibrations from the vehicle's runs, suspension
health."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Path, Query

from app.api.convert import calibration_public, vehicle_public
from app.api.deps import CalibrationId, CallerDep, CtxDep, PageDep, SessionDep, caller_name
from app.schemas.vehicles import (
    AnyVehicleParams,
    BogieParamsSchema,
    CalibrateRequest,
    CalibrationAccepted,
    CalibrationPublic,
    CalibrationsPublic,
    HealthAlertPublic,
    HealthPointPublic,
    VehicleCreate,
    VehicleEdit,
    VehicleEditPreview,
    VehicleHealthPublic,
    VehicleParamsSchema,
    VehiclePublic,
    VehicleRestore,
    VehiclesPublic,
    VehicleVersionPublic,
    VehicleVersionsPublic,
)
from app.services import lookup
from app.services.lookup import get_vehicle
from app.services.vehicles import calibration
from app.services.vehicles import versions as vehicles
from engine.bogie import BogieParams
from engine.vehicle_kinds import KIND_PRESETS

router = APIRouter(prefix="/vehicles", tags=["vehicles"])


@router.get("", response_model=VehiclesPublic)
def list_vehicles(session: SessionDep, page: PageDep) -> VehiclesPublic:
    """Vehicles by name (``table1``, the paper's Table 1 vehicle, always exists)."""
    rows, count = lookup.list_vehicles(session, page.offset, page.limit)
    return VehiclesPublic(data=[vehicle_public(v) for v in rows], count=count)


@router.post("", response_model=VehiclePublic, status_code=201)
def create_vehicle(session: SessionDep, body: VehicleCreate, caller: CallerDep) -> VehiclePublic:
    """Create a vehicle from its parameters (SI; a half car, or ``kind: bogie`` with the
    whole-vehicle datasheet values), version 1, or from an engine preset (``preset``: table1,
    heavy, passenger_coach, freight_wagon) with the parameters given overriding it; 409 if
    the name is taken, 422 naming ``preset`` when there is no such preset."""
    params: dict[str, Any] = body.params.model_dump()
    if body.preset is not None:
        given = body.params.model_fields_set
        params = lookup.preset_params(body.preset, {k: params[k] for k in given})
    vehicle = vehicles.create_vehicle(
        session, body.name, body.description, params, caller_name(session, caller)
    )
    return vehicle_public(vehicle)


@router.get("/presets", response_model=dict[str, AnyVehicleParams])
def list_presets() -> dict[str, VehicleParamsSchema | BogieParamsSchema]:
    """The engine's vehicle presets by name, of every kind: usable as a vehicle name anywhere
    (uploads, simulate), and as ``preset`` when creating a vehicle."""
    return {
        name: (
            BogieParamsSchema(**p.to_dict())
            if p.kind == BogieParams.kind
            else VehicleParamsSchema(**p.to_dict())
        )
        for name, p in KIND_PRESETS.items()
    }


@router.get("/{vehicle}", response_model=VehiclePublic)
def read_vehicle(session: SessionDep, vehicle: str) -> VehiclePublic:
    """One vehicle, by id or name."""
    return vehicle_public(get_vehicle(session, vehicle))


@router.patch("/{vehicle}", response_model=VehiclePublic | VehicleEditPreview)
def edit_vehicle(
    ctx: CtxDep,
    session: SessionDep,
    vehicle: str,
    body: VehicleEdit,
    caller: CallerDep,
    dry_run: Annotated[
        bool, Query(description="Answer what the edit would do; store nothing")
    ] = False,
) -> VehiclePublic | VehicleEditPreview:
    """Change some parameters by hand: a new version; the vehicle's runs are reprocessed.

    422 naming the parameter, or the derived quantity (``quantity``), when the vehicle would
    not be physically plausible as a whole. With ``dry_run=true`` nothing is stored: the
    answer says which parameters would change, how many runs would be reprocessed and
    whether the vehicle would be plausible (and why not)."""
    v = get_vehicle(session, vehicle)
    if dry_run:
        p = vehicles.preview_edit(session, v, body.params)
        return VehicleEditPreview(
            vehicle=v.name, version=p.version, params=p.params, changes=p.changes,
            runs_reprocessed=p.runs_reprocessed, plausible=p.plausible, problems=p.problems,
            quantities=p.quantities,
        )  # fmt: skip
    _, queued = vehicles.edit_vehicle(
        session, v, body.params, created_by=caller_name(session, caller), note=body.note
    )
    if queued:
        ctx.wake_worker()
    return vehicle_public(v)


@router.post("/{vehicle}/versions/{version}/restore", response_model=VehiclePublic)
def restore_version(
    ctx: CtxDep,
    session: SessionDep,
    vehicle: str,
    version: Annotated[int, Path(ge=1, le=2**31 - 1)],
    caller: CallerDep,
    body: VehicleRestore | None = None,
) -> VehiclePublic:
    """Make an earlier version's parameters current again (as a new version) and reprocess
    the vehicle's runs with them, whatever the versions between produced; 404 for a version
    the vehicle never had. Restoring the current parameters changes nothing."""
    v = get_vehicle(session, vehicle)
    _, queued = vehicles.restore_version(
        session, v, version, created_by=caller_name(session, caller),
        note=None if body is None else body.note,
    )  # fmt: skip
    if queued:
        ctx.wake_worker()
    return vehicle_public(v)


@router.get("/{vehicle}/versions", response_model=VehicleVersionsPublic)
def list_versions(session: SessionDep, vehicle: str) -> VehicleVersionsPublic:
    """The vehicle's parameter versions (who or what made each), newest first."""
    v = get_vehicle(session, vehicle)
    rows = vehicles.versions_of(session, v.id)
    return VehicleVersionsPublic(
        vehicle=v.name,
        current=v.version,
        data=[VehicleVersionPublic.model_validate(r) for r in rows],
    )


@router.post("/{vehicle}/calibrate", response_model=CalibrationAccepted, status_code=202)
def calibrate_vehicle(
    ctx: CtxDep, session: SessionDep, vehicle: str, body: CalibrateRequest, caller: CallerDep
) -> CalibrationAccepted:
    """Calibrate the vehicle from its stored runs in the background; poll the calibration."""
    v = get_vehicle(session, vehicle)
    cal = calibration.request_calibration(
        session, v, run_ids=body.run_ids, fit=body.fit, apply=body.apply, load_kg=body.load_kg,
        created_by=caller_name(session, caller),
    )  # fmt: skip
    ctx.wake_worker()
    return CalibrationAccepted(id=cal.id, status="running")


@router.get("/{vehicle}/calibrations", response_model=CalibrationsPublic)
def list_calibrations(session: SessionDep, vehicle: str) -> CalibrationsPublic:
    """The vehicle's calibrations (at most 100), newest first."""
    v = get_vehicle(session, vehicle)
    rows = calibration.calibrations_of(session, v.id)
    return CalibrationsPublic(data=[calibration_public(c, v.name) for c in rows], count=len(rows))


@router.get("/{vehicle}/calibrations/{calibration_id}", response_model=CalibrationPublic)
def read_calibration(
    session: SessionDep, vehicle: str, calibration_id: CalibrationId
) -> CalibrationPublic:
    """One calibration: status, fitted parameters ± uncertainty, objective, runs, applied."""
    v = get_vehicle(session, vehicle)
    return calibration_public(calibration.get_calibration(session, v, calibration_id), v.name)


@router.get("/{vehicle}/health", response_model=VehicleHealthPublic)
def read_health(session: SessionDep, vehicle: str) -> VehicleHealthPublic:
    """Suspension health: calibrated parameters over time and changes beyond uncertainty."""
    v = get_vehicle(session, vehicle)
    history = calibration.health_history(session, v.id)
    alerts = calibration.vehicle_health(session, v.id)
    return VehicleHealthPublic(
        vehicle=v.name,
        alerts=[
            HealthAlertPublic(
                vehicle=v.name, parameter=a.parameter, before=a.before, after=a.after,
                before_sd=a.before_sd, after_sd=a.after_sd, change=a.change, sigmas=a.sigmas,
                since=a.since, reference=a.reference_label, source=a.label, message=a.message,
            )
            for a in alerts
        ],
        history=[
            HealthPointPublic(parameter=h.parameter, value=h.value, sd=h.sd, at=h.at,
                              source=h.label)
            for h in history
        ],
    )  # fmt: skip
