"""Synthetic runs: the engine's forward model and sensor, then processed like an upload."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from app.core.errors import ApiError
from app.schemas.simulate import SimulateRequest, TruthPublic
from engine.errors import ParameterError
from engine.sensor import SensorModel
from engine.synthetic import REALISTIC_SENSOR, make_run
from engine.track import SoftZone, TrackParams
from engine.vehicle import VehicleParams

from .context import AppContext
from .logs import sha256_hex
from .submit import Submission, resolve_track, resolve_vehicle, submit

END_MARGIN_M = 10.0
TRUTH_POINTS = 5000


def _sensor(spec: SimulateRequest) -> SensorModel:
    if spec.sensor == "ideal":
        return SensorModel()
    if spec.sensor == "realistic":
        return REALISTIC_SENSOR
    return SensorModel(**spec.sensor.model_dump())


def _check_geometry(ctx: AppContext, body: SimulateRequest, vp: VehicleParams) -> None:
    for i, z in enumerate(body.zones):
        if z.end_m > body.length_m:
            raise ApiError(
                422, f"zone {i} ends at {z.end_m} m, beyond the {body.length_m} m track",
                field=f"zones.{i}.end_m",
            )  # fmt: skip
    if body.start_chainage_m > body.length_m:
        raise ApiError(
            422, f"start_chainage_m {body.start_chainage_m} m is beyond the track end",
            field="start_chainage_m",
        )  # fmt: skip
    if body.direction == "increasing":
        room = body.length_m - END_MARGIN_M - (body.start_chainage_m + vp.d1)
        rear = body.start_chainage_m - vp.d2
    else:
        room = body.start_chainage_m - vp.d1 - END_MARGIN_M
        rear = body.length_m - (body.start_chainage_m + vp.d2)
    if rear < 0:
        raise ApiError(
            422,
            f"the rear axle would start off the track: start_chainage_m must leave {vp.d2} m "
            "(the vehicle's d2) behind the body centre",
            field="start_chainage_m",
        )
    if room <= 0:
        raise ApiError(
            422, "no room to run: the start chainage is too close to the end of the track",
            field="start_chainage_m",
        )  # fmt: skip
    duration = room / body.speed_mps
    limit = ctx.settings.simulate_max_duration_s
    if duration > limit:
        raise ApiError(
            422,
            f"the run would last {duration:.0f} s of travel; at most {limit:.0f} s are simulated "
            f"(shorten length_m or raise speed_mps)",
            field="length_m",
        )


def simulate_and_submit(ctx: AppContext, body: SimulateRequest) -> tuple[int, bool, TruthPublic]:
    """Simulate the run ``body`` describes and store it; returns ``(run_id, created, truth)``.

    Raises
    ------
    ApiError
        422 when the geometry does not fit (zones beyond the track, no room to run, too long).
    """
    with ctx.db.session() as s:
        vehicle = resolve_vehicle(s, body.vehicle, None)
        vp = VehicleParams.from_dict(vehicle.params_dict())
        track = resolve_track(s, body.track, None)
        tp = TrackParams.from_dict(track.params_dict()) if track is not None else TrackParams()
    _check_geometry(ctx, body, vp)
    zones = tuple(SoftZone(z.start_m, z.end_m, z.loss) for z in body.zones)
    try:
        with ctx.slots:
            syn = make_run(
                length=body.length_m,
                zones=zones,
                speed=body.speed_mps,
                start_chainage_m=body.start_chainage_m,
                direction=body.direction,
                jitter=body.jitter,
                sensor=_sensor(body),
                seed=body.seed,
                vehicle=vp,
                params=tp,
                end_margin_m=END_MARGIN_M,
            )
    except ParameterError as exc:
        raise ApiError(422, str(exc), kind="ParameterError") from None
    step = 0.25
    lo = min(float(syn.sim.x_front.min()), float(syn.sim.x_rear.min()))
    hi = max(float(syn.sim.x_front.max()), float(syn.sim.x_rear.max()))
    grid = np.arange(math.ceil(lo / step) * step, hi + 1e-9, step)
    level = syn.true_profile(grid)
    stride = max(1, math.ceil(grid.size / TRUTH_POINTS))
    truth = TruthPublic(
        zones=list(body.zones),
        chainage_m=grid[::stride].tolist(),
        level_mm=[None if not math.isfinite(v) else v for v in level[::stride].tolist()],
    )
    request: dict[str, Any] = body.model_dump(mode="json")
    # Same request, vehicle and track: same run (the simulation is deterministic in its seed).
    fingerprint = json.dumps(
        {"request": request, "vehicle": vp.to_dict(), "track": tp.to_dict()}, sort_keys=True
    )
    sub = Submission(
        log=syn.log,
        source="simulate",
        content_hash=sha256_hex(fingerprint.encode()),
        track=body.track,
        vehicle=vehicle.name,
        name=body.name,
        start_chainage_m=body.start_chainage_m,
        direction=body.direction,
        recorded_at=body.recorded_at,
        options={"simulation": request},
        extra_signals={"truth": truth.model_dump(mode="json")},
    )
    run_id, created = submit(ctx, sub)
    return run_id, created, truth
