"""ORM rows to public schemas (aligned chainage: stored chainage + the run's offset)."""

from __future__ import annotations

from typing import Any

from app.db.models import Calibration, Run, Track, Vehicle
from app.schemas.runs import (
    DetectionLimitPublic,
    RunAlignmentPublic,
    RunError,
    RunPositioningPublic,
    RunPublic,
)
from app.schemas.tracks import TrackPublic
from app.schemas.vehicles import (
    CalibrationPublic,
    FittedParameterPublic,
    VehiclePublic,
)
from app.services.stiffness import run_stiffness_basis

_PROGRESS = {"queued": 0.05, "inverting": 0.35, "storing": 0.85}


def run_public(run: Run) -> RunPublic:
    """The public view of a run."""
    lo, hi = run.aligned_extent()
    progress = 1.0 if run.status != "processing" else _PROGRESS.get(run.stage or "queued", 0.05)
    basis, message = run_stiffness_basis(run.single_pass_valid)
    return RunPublic(
        id=run.id,
        name=run.name,
        track_id=run.track_id,
        track=run.track.name,
        vehicle_id=run.vehicle_id,
        vehicle=run.vehicle.name,
        vehicle_version=run.vehicle_version,
        source=run.source,
        original_filename=run.original_filename,
        recorded_at=run.recorded_at,
        created_at=run.created_at,
        processed_at=run.processed_at,
        start_chainage_m=run.start_chainage_m,
        direction=run.direction,  # type: ignore[arg-type]
        sample_rate_hz=run.sample_rate_hz,
        n_samples=run.n_samples,
        duration_s=run.duration_s,
        speed_min_mps=run.speed_min_mps,
        speed_max_mps=run.speed_max_mps,
        chainage_min_m=lo,
        chainage_max_m=hi,
        chainage_offset_m=run.offset_m,
        alignment=_alignment(run),
        status=run.status,  # type: ignore[arg-type]
        stage=run.stage if run.status == "processing" else None,  # type: ignore[arg-type]
        progress=progress,
        error=RunError.model_validate(run.error) if run.error else None,
        quality=run.quality,
        method=run.method,
        n_soft_spots=run.n_soft_spots,
        processing_s=run.processing_s,
        payload_kg=run.payload_kg,
        static_wheel_load_n=run.static_wheel_load_n,
        mean_wheel_force_n=run.mean_wheel_force_n,
        stiffness_basis=basis,  # type: ignore[arg-type]
        stiffness_message=message,
        detection_limit=(
            DetectionLimitPublic.model_validate(run.detection_limit)
            if run.detection_limit
            else None
        ),
        content_hash=run.content_hash,
        options=run.options or {},
        positioning=(
            RunPositioningPublic.model_validate(run.positioning) if run.positioning else None
        ),
        detail_expired_at=run.detail_expired_at,
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


def track_public(track: Track, n_runs: int = 0) -> TrackPublic:
    """The public view of a track."""
    return TrackPublic(
        id=track.id,
        name=track.name,
        description=track.description,
        rail=track.rail,
        k_nominal=track.k_nominal,
        spacing=track.spacing,
        EI=track.EI,
        mass_per_m=track.mass_per_m,
        c_support=track.c_support,
        created_at=track.created_at,
        n_runs=n_runs,
    )


def vehicle_public(vehicle: Vehicle) -> VehiclePublic:
    """The public view of a vehicle."""
    return VehiclePublic(
        id=vehicle.id,
        name=vehicle.name,
        description=vehicle.description,
        params=dict(vehicle.params_dict()),
        version=vehicle.version,
        created_at=vehicle.created_at,
    )


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
