"""Synthetic runs: the engine's forward model and sensor, then processed like an upload."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from app.services.context import AppContext
from app.services.errors import Invalid
from app.services.lookup import resolve_track, resolve_vehicle
from app.services.run_lifecycle.accept import submit
from app.services.run_lifecycle.intake import Submission
from app.services.run_lifecycle.logs import sha256_hex
from engine.chainage import axle_grid
from engine.errors import ParameterError
from engine.irregularity import SPECTRA
from engine.sensor import SensorModel
from engine.simulate import room_to_run
from engine.synthetic import make_run
from engine.track import SoftZone, TrackParams
from engine.vehicle_kinds import Vehicle as EngineVehicle
from engine.vehicle_kinds import vehicle_from_dict

TRUTH_POINTS = 5000
"""Most points of the true profile returned with a simulated run."""


@dataclass(frozen=True)
class SimulationSpec:
    """A synthetic run: a straight track with soft zones, the vehicle at constant speed.

    ``record`` is what the client asked, as JSON: stored with the run and, with the vehicle
    and track, its fingerprint (the same request stores the same run once).
    """

    track: str
    vehicle: str | None
    name: str | None
    length_m: float
    speed_mps: float
    zones: tuple[SoftZone, ...]
    start_chainage_m: float
    direction: str
    sensor: SensorModel
    jitter: float
    seed: int
    recorded_at: datetime | None = None
    record: dict[str, Any] = field(default_factory=dict)
    irregularity: str | None = None
    """Spectrum name of the unloaded rail geometry (None: a straight rail)."""
    irregularity_seed: int | None = None
    """Seed of the geometry and of the support scatter (the same physical track)."""


@dataclass(frozen=True)
class Truth:
    """What was simulated: the zones and the true fused loaded level (chainage m, level mm)."""

    zones: tuple[SoftZone, ...]
    chainage_m: list[float]
    level_mm: list[float | None]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, zones as ``{"start_m", "end_m", "loss"}``."""
        return {
            "zones": [{"start_m": z.start_m, "end_m": z.end_m, "loss": z.loss} for z in self.zones],
            "chainage_m": list(self.chainage_m),
            "level_mm": list(self.level_mm),
        }


def _check_geometry(ctx: AppContext, spec: SimulationSpec, vp: EngineVehicle) -> None:
    for i, z in enumerate(spec.zones):
        if z.end_m > spec.length_m:
            raise Invalid(
                f"zone {i} ends at {z.end_m} m, beyond the {spec.length_m} m track",
                field=f"zones.{i}.end_m",
            )
    try:
        room = room_to_run(spec.length_m, spec.start_chainage_m, spec.direction, vp)
    except ParameterError as exc:
        raise Invalid.from_engine(exc) from None
    duration = room / spec.speed_mps
    limit = ctx.settings.simulate_max_duration_s
    if duration > limit:
        raise Invalid(
            f"the run would last {duration:.0f} s of travel; at most {limit:.0f} s are simulated "
            f"(shorten length_m or raise speed_mps)",
            field="length_m",
        )


def simulate_and_submit(ctx: AppContext, spec: SimulationSpec) -> tuple[int, bool, Truth]:
    """Simulate the run ``spec`` describes and store it; returns ``(run_id, created, truth)``.

    Raises
    ------
    Invalid
        The geometry does not fit (zones beyond the track, no room to run, too long a run) or
        the engine refuses a value; the vehicle is unknown.
    """
    with ctx.db.session() as s:
        vehicle = resolve_vehicle(s, spec.vehicle, None)
        vp = vehicle_from_dict(vehicle.params_dict())
        track = resolve_track(s, spec.track, None)
        tp = TrackParams.from_dict(track.params_dict()) if track is not None else TrackParams()
    _check_geometry(ctx, spec, vp)
    if spec.irregularity is not None and spec.irregularity not in SPECTRA:
        raise Invalid(
            f"unknown spectrum {spec.irregularity!r}; expected one of {', '.join(SPECTRA)}",
            field="irregularity.spectrum",
        )
    try:
        with ctx.slots:
            syn = make_run(
                length=spec.length_m,
                zones=spec.zones,
                speed=spec.speed_mps,
                start_chainage_m=spec.start_chainage_m,
                direction=spec.direction,
                jitter=spec.jitter,
                sensor=spec.sensor,
                seed=spec.seed,
                vehicle=vp,
                params=tp,
                irregularity=spec.irregularity,
                track_seed=spec.irregularity_seed,
            )
    except ParameterError as exc:
        raise Invalid.from_engine(exc) from None
    grid = axle_grid(syn.sim.x_front, syn.sim.x_rear)
    level = syn.true_profile(grid)
    stride = max(1, math.ceil(grid.size / TRUTH_POINTS))
    truth = Truth(
        zones=spec.zones,
        chainage_m=grid[::stride].tolist(),
        level_mm=[None if not math.isfinite(v) else v for v in level[::stride].tolist()],
    )
    # Same request, vehicle and track: same run (the simulation is deterministic in its seed).
    # The date is not the log: dated otherwise it is the same pass (as an upload's file is),
    # and null in the fingerprint keeps the runs stored before this rule found.
    request = {**spec.record, "recorded_at": None} if "recorded_at" in spec.record else spec.record
    fingerprint = json.dumps(
        {"request": request, "vehicle": vp.to_dict(), "track": tp.to_dict()}, sort_keys=True
    )
    sub = Submission(
        log=syn.log,
        source="simulate",
        content_hash=sha256_hex(fingerprint.encode()),
        track=spec.track,
        vehicle=vehicle.name,
        name=spec.name,
        start_chainage_m=spec.start_chainage_m,
        direction=spec.direction,
        recorded_at=spec.recorded_at,
        options={"simulation": spec.record},
        extra_signals={"truth": truth.to_dict()},
    )
    run_id, created = submit(ctx, sub)
    return run_id, created, truth
