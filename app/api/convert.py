"""Between the public schemas and the services: ORM rows and service results to public views
(aligned chainage: stored chainage + the run's offset), requests to the services' plain specs."""

from __future__ import annotations

from typing import Any, TypeVar

from pydantic import BaseModel

from app.db.models import Calibration, Run, Survey, Track, Vehicle
from app.schemas.runs import (
    DetectionLimitPublic,
    RunAlignmentPublic,
    RunError,
    RunPositioningPublic,
    RunPublic,
)
from app.schemas.simulate import SimulateRequest
from app.schemas.stiffness import SurveyPublic
from app.schemas.tracks import TrackPublic
from app.schemas.vehicles import (
    CalibrationPublic,
    FittedParameterPublic,
    VehiclePublic,
)
from app.services.errors import Invalid
from app.services.run_lifecycle.simulation import SimulationSpec
from app.services.track.alignment import GRID_STEP_M
from app.services.track.separation_store import StiffnessWindow, run_stiffness_basis
from app.services.track.separation_trust import TRUSTED
from app.services.views.window import Window
from engine.sensor import SensorModel, sensor_for_grade
from engine.synthetic import REALISTIC_SENSOR
from engine.track import SoftZone

M = TypeVar("M", bound=BaseModel)

_PROGRESS = {"queued": 0.05, "inverting": 0.35, "storing": 0.85}


def from_row(model: type[M], row: Any, **derived: Any) -> M:
    """``model`` from an ORM row: each field the row's attribute of the same name, but for
    the fields ``derived`` (renamed, computed or aligned ones), given."""
    same = {name: getattr(row, name) for name in model.model_fields if name not in derived}
    return model(**same, **derived)


def run_public(run: Run) -> RunPublic:
    """The public view of a run."""
    lo, hi = run.aligned_extent()
    progress = 1.0 if run.status != "processing" else _PROGRESS.get(run.stage or "queued", 0.05)
    basis, message = run_stiffness_basis(run.single_pass_valid)
    return from_row(
        RunPublic,
        run,
        track=run.track.name,
        vehicle=run.vehicle.name,
        chainage_min_m=lo,
        chainage_max_m=hi,
        chainage_offset_m=run.offset_m,
        alignment=_alignment(run),
        stage=run.stage if run.status == "processing" else None,
        progress=progress,
        error=RunError.model_validate(run.error) if run.error else None,
        stiffness_basis=basis,
        stiffness_message=message,
        detection_limit=(
            DetectionLimitPublic.model_validate(run.detection_limit)
            if run.detection_limit
            else None
        ),
        options=run.options or {},
        positioning=(
            RunPositioningPublic.model_validate(run.positioning) if run.positioning else None
        ),
    )


def _alignment(run: Run) -> RunAlignmentPublic | None:
    if run.alignment_status is None:
        return None
    return RunAlignmentPublic(
        status=run.alignment_status,  # type: ignore[arg-type]
        offset_m=run.offset_m,
        correlation=run.alignment_correlation,
        overlap_m=run.alignment_overlap_m,
        reason=run.alignment_reason,
    )


def track_public(track: Track, n_runs: int = 0, has_centerline: bool = False) -> TrackPublic:
    """The public view of a track."""
    return from_row(TrackPublic, track, n_runs=n_runs, has_centerline=has_centerline)


def vehicle_public(vehicle: Vehicle) -> VehiclePublic:
    """The public view of a vehicle."""
    return from_row(VehiclePublic, vehicle, params=dict(vehicle.params_dict()))


def calibration_public(cal: Calibration, vehicle_name: str) -> CalibrationPublic:
    """The public view of a calibration (a queued one shows as ``running``)."""
    res = cal.result or {}
    req = cal.request or {}
    keys = ("runs", "skipped", "scans", "n_evaluations", "seconds", "registered", "apply_note")
    details: dict[str, Any] | None = {k: res[k] for k in keys if k in res} if res else None
    return CalibrationPublic(
        id=cal.id,
        vehicle=vehicle_name,
        status="running" if cal.status in ("queued", "running") else cal.status,  # type: ignore[arg-type]
        automatic=cal.automatic,
        created_by=cal.created_by,
        created_at=cal.created_at,
        finished_at=cal.finished_at,
        runs_used=list(req.get("run_ids") or []),
        fit=req.get("fit"),
        apply=bool(req.get("apply")),
        load_kg=req.get("load_kg"),
        vehicle_version=res.get("vehicle_version"),
        params=res.get("params"),
        fitted=[FittedParameterPublic(**f) for f in res.get("fitted", [])],
        objective_before=res.get("objective_before"),
        objective_after=res.get("objective_after"),
        disagreement_before_mm=res.get("disagreement_before_mm"),
        disagreement_after_mm=res.get("disagreement_after_mm"),
        significant=res.get("significant"),
        message=res.get("message"),
        not_identified=res.get("not_identified", {}),
        applied=cal.applied,
        applied_version=cal.applied_version,
        details=details,
        error=cal.error,
    )


def survey_public(s: Survey, duplicate: bool = False) -> SurveyPublic:
    """A survey's public view (chainage aligned)."""
    off = s.chainage_offset_m or 0.0
    return from_row(
        SurveyPublic, s, chainage_min_m=s.chainage_min_m + off,
        chainage_max_m=s.chainage_max_m + off, chainage_offset_m=off, duplicate=duplicate,
    )  # fmt: skip


def stiffness_public(trk: Track, window: Window, sep: StiffnessWindow) -> dict[str, Any]:
    """A window of the track's separated stiffness as :class:`StiffnessPublic` states it, as
    plain data (serialised once by orjson: the response-model pass would double the time of a
    long window)."""
    cols = sep.columns
    return {
        "track_id": trk.id,
        "track": trk.name,
        "from_m": window.from_m,
        "to_m": window.to_m,
        "grid_step_m": GRID_STEP_M,
        "k_nominal_n_per_m": trk.k_nominal,
        "n": sep.n,
        "separable": sep.separable,
        "separable_fraction": sep.separable_fraction,
        "message": sep.message,
        "not_separable": [st.to_dict() for st in sep.not_separable],
        "updating": sep.updating,
        "chainage_m": cols["chainage_m"],
        "k_rel": cols["k_rel"],
        "k_rel_lo": cols["k_rel_lo"],
        "k_rel_hi": cols["k_rel_hi"],
        "geometry_mm": cols["geometry_mm"],
        "geometry_sd_mm": cols["geometry_sd_mm"],
        "compliance_mm_per_kn": cols["compliance_mm_per_kn"],
        "n_passes": cols["n_passes"],
        "load_ratio": cols["load_ratio"],
        "separable_at": cols["separable"],
        "soft_spots": [
            {
                "start_m": s.start_m,
                "end_m": s.end_m,
                "peak_m": s.peak_m,
                "stiffness_loss_pct": s.loss_pct,
                "loss_lo_pct": s.loss_lo_pct,
                "loss_hi_pct": s.loss_hi_pct,
                "confidence": s.confidence,
                "basis": "separated",
            }  # fmt: skip
            | (sep.spot_trust[i] if sep.spot_trust else TRUSTED).to_dict()
            for i, s in enumerate(sep.spots)
        ],
        "contributors": sep.contributors,
    } | sep.trust.to_dict()


def simulation_spec(body: SimulateRequest) -> SimulationSpec:
    """The service's plain description of a simulate request (engine types, the sensor chosen)."""
    if body.sensor_grade is not None:
        if "sensor" in body.model_fields_set:
            raise Invalid("give either sensor or sensor_grade, not both", field="sensor_grade")
        # the simulation's rate (1 kHz) is the log's; the seed draws the pass's bias
        sensor = sensor_for_grade(body.sensor_grade, 1000.0, seed=body.seed)
    elif body.sensor == "ideal":
        sensor = SensorModel()
    elif body.sensor == "realistic":
        sensor = REALISTIC_SENSOR
    else:
        sensor = SensorModel(**body.sensor.model_dump())
    return SimulationSpec(
        track=body.track or body.simulated_track_name(),
        vehicle=body.vehicle,
        name=body.name,
        length_m=body.length_m,
        speed_mps=body.speed_mps,
        zones=tuple(SoftZone(z.start_m, z.end_m, z.loss) for z in body.zones),
        start_chainage_m=body.start_chainage_m,
        direction=body.direction,
        sensor=sensor,
        jitter=body.jitter,
        seed=body.seed,
        recorded_at=body.recorded_at,
        # without a grade the record is what it was before grades (the same fingerprint)
        record=body.model_dump(
            mode="json", exclude={"sensor_grade"} if body.sensor_grade is None else None
        ),
        irregularity=None if body.irregularity is None else body.irregularity.spectrum,
        irregularity_seed=None if body.irregularity is None else body.irregularity.seed,
    )
