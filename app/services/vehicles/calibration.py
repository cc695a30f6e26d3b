"""Calibrating a vehicle from its stored runs, in the background; suspension health.

A calibration request is a ``calibrations`` row (``queued``); the background worker claims it
like a run (``claimed_by`` + heartbeat, taken over when the heartbeat stops), fits the vehicle
with :func:`engine.calibration.calibrate` on the runs' stored logs and stores the result. With
``apply`` a significant result becomes the vehicle's next parameter version and its runs are
reprocessed; a result that is not significant is never applied (it would not improve the runs,
and might worsen them).
"""

from __future__ import annotations

import logging
from datetime import datetime
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.db.base import utcnow
from app.db.models import Calibration, Run, RunInput, Vehicle
from app.services.errors import Conflict, Invalid, NotFound
from app.services.run_lifecycle.logs import unpack_log
from app.services.vehicles.loads import declared_body_mass
from app.services.vehicles.versions import checked_params, new_version
from engine.calibration import (
    FITTABLE,
    CalibrationConfig,
    CalibrationRun,
    calibrate,
    held_vehicle,
)
from engine.errors import ParameterError
from engine.health import HealthAlert, ParameterEstimate, health_alerts
from engine.vehicle_kinds import Vehicle as EngineVehicle
from engine.vehicle_kinds import vehicle_from_dict
from engine.vehicle_plausibility import VehicleImplausible, implausibilities

log = logging.getLogger(__name__)

ACTIVE = ("queued", "running")
"""States of a calibration that is not finished."""

HEALTH_PARAMETERS = tuple(
    sorted({t for f in FITTABLE.values() if f.kind == "scale" for t in (*f.targets, *f.bogie)})
)
"""Vehicle parameters whose calibrated history is watched (suspension and body): every
parameter a scale quantity of calibration moves, on any kind (a half car's Is, ks1, ks2, cs1,
cs2; a bogie vehicle's pitch inertia, secondary and primary)."""


def _config(fit: list[str] | None, load_kg: float | None) -> CalibrationConfig:
    try:
        if fit is None:
            return CalibrationConfig(load_kg=load_kg)
        return CalibrationConfig(fit=tuple(fit), load_kg=load_kg)
    except ParameterError as exc:
        field = "load_kg" if "load_kg" in str(exc) else "fit"
        raise Invalid.from_engine(exc, field=field) from None


def _chosen_runs(session: Session, vehicle: Vehicle, run_ids: list[int]) -> list[int]:
    """The runs a calibration request names, sorted; Invalid unless each exists, was logged
    by ``vehicle``, is processed and has its log stored."""
    if not run_ids:
        raise Invalid("run_ids is empty: give some runs, or leave it out for all", field="run_ids")
    ids = sorted(set(run_ids))
    rows = {r.id: r for r in session.scalars(select(Run).where(Run.id.in_(ids))).all()}
    missing = [i for i in ids if i not in rows]
    if missing:
        raise Invalid(f"run(s) {missing} do not exist", field="run_ids")
    foreign = [i for i in ids if rows[i].vehicle_id != vehicle.id]
    if foreign:
        names = ", ".join(f"{i} ({rows[i].vehicle.name})" for i in foreign)
        raise Invalid(
            f"run(s) {names} were logged by another vehicle, not {vehicle.name!r}",
            field="run_ids",
        )
    stored = set(session.scalars(select(RunInput.run_id).where(RunInput.run_id.in_(ids))))
    not_done = [i for i in ids if rows[i].status != "done" or i not in stored]
    if not_done:
        raise Invalid(
            f"run(s) {not_done} are not processed or have no stored log to calibrate from",
            field="run_ids",
        )
    return ids


def request_calibration(
    session: Session,
    vehicle: Vehicle,
    *,
    run_ids: list[int] | None = None,
    fit: list[str] | None = None,
    apply: bool = False,
    load_kg: float | None = None,
    created_by: str | None = None,
    automatic: bool = False,
) -> Calibration:
    """Queue a calibration of ``vehicle`` (commits).

    Parameters
    ----------
    run_ids : list of int, optional
        Runs to use (default: every processed run of the vehicle whose log is stored).
    fit : list of str, optional
        Quantities to fit (names of ``engine.calibration.FITTABLE`` the vehicle's kind has;
        default ``engine.calibration.DEFAULT_FIT_BY_KIND``: I_s, k_s1, k_s2 on a half car,
        I_s and the secondary k_s on a bogie vehicle).
    apply : bool
        Make a significant result the vehicle's next version and reprocess its runs.
    load_kg : float, optional
        Known body mass, kg (the only way to change the mass).

    Raises
    ------
    Invalid
        Unknown fit names, a bad load, runs of another vehicle or unknown, no usable run.
    Conflict
        A calibration of this vehicle is already queued or running.
    """
    # checked now, so a bad request changes nothing
    registered = vehicle_from_dict(vehicle.params_dict())
    try:
        _config(fit, load_kg).fit_for(registered.kind)
    except ParameterError as exc:
        raise Invalid.from_engine(exc, field="fit") from None
    if load_kg is not None:
        # the body mass must make a vehicle with the rest (and lie in its own range)
        try:
            held = held_vehicle(registered, load_kg)
        except ParameterError as exc:
            raise Invalid.from_engine(exc, field="load_kg") from None
        checked_params(held.to_dict(), field="load_kg")
    ids = (
        usable_run_ids(session, vehicle.id)
        if run_ids is None
        else _chosen_runs(session, vehicle, run_ids)
    )
    if not ids:
        raise Invalid(
            f"vehicle {vehicle.name!r} has no processed runs with a stored log to calibrate from",
            field="run_ids",
        )
    active = session.scalar(
        select(Calibration.id).where(
            Calibration.vehicle_id == vehicle.id, Calibration.status.in_(ACTIVE)
        )
    )
    if active is not None:
        raise Conflict(
            f"calibration {active} of vehicle {vehicle.name!r} is still running", field="vehicle"
        )
    cal = Calibration(
        vehicle_id=vehicle.id,
        status="queued",
        request={"run_ids": ids, "fit": fit, "apply": bool(apply), "load_kg": load_kg},
        applied=False,
        automatic=automatic,
        created_by=created_by,
        attempts=0,
    )
    session.add(cal)
    session.commit()
    return cal


def usable_run_ids(session: Session, vehicle_id: int, after: datetime | None = None) -> list[int]:
    """Processed runs of the vehicle with a stored log (created after ``after``), by id."""
    q = (
        select(Run.id)
        .join(RunInput, RunInput.run_id == Run.id)
        .where(Run.vehicle_id == vehicle_id, Run.status == "done")
    )
    if after is not None:
        q = q.where(Run.created_at > after)
    return list(session.scalars(q.order_by(Run.id)).all())


def get_calibration(session: Session, vehicle: Vehicle, calibration_id: int) -> Calibration:
    """A calibration of this vehicle; NotFound otherwise."""
    cal = session.get(Calibration, calibration_id)
    if cal is None or cal.vehicle_id != vehicle.id:
        raise NotFound(
            f"calibration {calibration_id} of vehicle {vehicle.name!r} not found",
            field="calibration_id",
        )
    return cal


def calibrations_of(session: Session, vehicle_id: int, limit: int = 100) -> list[Calibration]:
    """The vehicle's calibrations, newest first."""
    return list(
        session.scalars(
            select(Calibration)
            .where(Calibration.vehicle_id == vehicle_id)
            .order_by(Calibration.id.desc())
            .limit(limit)
        ).all()
    )


def maybe_auto_calibrate(session: Session, vehicle_id: int, every_n_runs: int) -> int | None:
    """Queue an automatic calibration once the vehicle has ``every_n_runs`` new runs.

    New: processed (with a stored log) since the vehicle's last calibration was requested;
    runs reprocessed in place are not new. Returns the calibration id, or None. Commits.
    """
    if every_n_runs <= 0:
        return None
    vehicle = session.get(Vehicle, vehicle_id)
    if vehicle is None:
        return None
    last = session.scalar(
        select(func.max(Calibration.created_at)).where(Calibration.vehicle_id == vehicle_id)
    )
    ids = usable_run_ids(session, vehicle_id, after=last)
    if len(ids) < every_n_runs:
        return None
    try:
        cal = request_calibration(
            session, vehicle, run_ids=ids, apply=True, created_by="automatic", automatic=True
        )
    except (Conflict, Invalid):  # one already running, or the runs went meanwhile
        session.rollback()
        return None
    log.info("automatic calibration %s of vehicle %s (%d new runs)", cal.id, vehicle_id, len(ids))
    return cal.id


def calibration_inputs(
    session: Session, cal: Calibration
) -> tuple[EngineVehicle, int, list[CalibrationRun], datetime | None, datetime | None]:
    """The registered vehicle (and its version) and the stored runs a calibration uses."""
    vehicle = session.get(Vehicle, cal.vehicle_id)
    assert vehicle is not None
    vp = vehicle_from_dict(vehicle.params_dict())
    held = held_vehicle(vp, cal.request.get("load_kg"))
    runs: list[CalibrationRun] = []
    times: list[datetime] = []
    for run_id in cal.request.get("run_ids") or []:
        run = session.get(Run, run_id)
        data = session.scalar(select(RunInput.data).where(RunInput.run_id == run_id))
        if run is None or data is None:
            continue  # deleted since the request: the rest is used
        # A run with a declared load is compared at the body mass it was inverted with (the
        # engine skips it, saying why, when that mass is not plausible for the vehicle).
        body_mass = declared_body_mass(held, run.payload_kg, run.static_wheel_load_n)
        runs.append(
            CalibrationRun(
                unpack_log(data), run.start_chainage_m, run.direction, f"run {run_id}",
                body_mass_kg=body_mass,
            )
        )  # fmt: skip
        times.append(run.recorded_at or run.created_at)
    return (
        vp,
        vehicle.version,
        runs,
        (min(times) if times else None),
        (max(times) if times else None),
    )


def fit_calibration(
    vehicle: EngineVehicle, runs: list[CalibrationRun], request: dict[str, Any]
) -> dict[str, Any]:
    """Run the engine's calibration; the stored result (JSON-safe)."""
    cfg = _config(request.get("fit"), request.get("load_kg"))
    if not runs:
        raise ParameterError("none of the requested runs is stored any more")
    return calibrate(runs, vehicle, cfg).to_dict()


def store_calibration(
    session: Session,
    cal: Calibration,
    result: dict[str, Any],
    base_version: int,
    runs_from: datetime | None,
    runs_to: datetime | None,
) -> int:
    """Store a finished calibration; apply it when asked and significant. Caller commits.

    Returns how many runs were queued for reprocessing.
    """
    vehicle = session.get(Vehicle, cal.vehicle_id)
    assert vehicle is not None
    result = dict(result, vehicle_version=base_version)
    queued = 0
    applied = False
    if cal.request.get("apply"):
        if not result["significant"]:
            result["apply_note"] = "not applied: no significant change"
        elif vehicle.version != base_version:
            result["apply_note"] = (
                f"not applied: the vehicle changed meanwhile (version {base_version} -> "
                f"{vehicle.version}); calibrate again"
            )
        elif found := implausibilities(params := vehicle_from_dict(result["params"]), params.kind):
            result["apply_note"] = "not applied: " + VehicleImplausible(found).args[0]
        else:
            version, queued = new_version(
                session, vehicle, params, source="calibration",
                created_by=cal.created_by or ("automatic" if cal.automatic else None),
                calibration_id=cal.id, note=result["message"],
            )  # fmt: skip
            cal.applied_version = version
            applied = True
    cal.applied = applied
    cal.result = result
    cal.status = "done"
    cal.error = None
    cal.runs_from, cal.runs_to = runs_from, runs_to
    cal.finished_at = utcnow()
    return queued


def health_history(session: Session, vehicle_id: int) -> list[ParameterEstimate]:
    """The vehicle's calibrated parameters over time (every finished calibration)."""
    out: list[ParameterEstimate] = []
    cals = session.scalars(
        select(Calibration)
        .where(Calibration.vehicle_id == vehicle_id, Calibration.status == "done")
        .order_by(Calibration.id)
    ).all()
    for cal in cals:
        res = cal.result or {}
        at = cal.runs_from or cal.created_at
        for f in res.get("fitted", []):
            if not f.get("identified") or f.get("at_bound"):  # a bound is no estimate
                continue
            for name, value in f["after"].items():
                if name not in HEALTH_PARAMETERS:
                    continue
                sd = abs(f["sd"] * value)  # relative uncertainty of a scale quantity
                out.append(ParameterEstimate(name, value, sd, at, f"calibration {cal.id}"))
    return out


def vehicle_health(session: Session, vehicle_id: int) -> list[HealthAlert]:
    """Suspension-health alerts of a vehicle: calibrated parameters that changed beyond
    their uncertainty (engine.health)."""
    return health_alerts(health_history(session, vehicle_id))
