"""Simulation schemas: a synthetic run from the engine's forward model, processed like an upload."""

from __future__ import annotations

import hashlib
import json
from typing import Any, Literal

from pydantic import BaseModel, Field, field_validator, model_validator

from engine.irregularity import SPECTRA
from engine.sensor import SENSOR_GRADES

from .common import CHAINAGE_LIMIT_M, Name, StrictModel, Timestamp, closed_list
from .runs import Direction, RunCreated


class ZoneSpec(StrictModel):
    """A soft zone: supports from ``start_m`` to ``end_m`` lose ``loss`` of their stiffness."""

    start_m: float = Field(ge=0, allow_inf_nan=False, description="First affected support, m")
    end_m: float = Field(ge=0, allow_inf_nan=False, description="Last affected support, m")
    loss: float = Field(ge=0, lt=1, description="Fraction of stiffness lost (0.4 = 40 %)")

    @model_validator(mode="before")
    @classmethod
    def _from_text(cls, data: Any) -> Any:
        # "60:65:0.5", as the engine's CLI takes it
        if isinstance(data, str):
            parts = data.split(":")
            if len(parts) != 3:
                raise ValueError("a zone text must be 'start_m:end_m:loss', e.g. '60:65:0.5'")
            return dict(zip(("start_m", "end_m", "loss"), parts, strict=True))
        return data

    @model_validator(mode="after")
    def _ordered(self) -> ZoneSpec:
        if self.end_m < self.start_m:
            raise ValueError(f"zone end {self.end_m} m is before its start {self.start_m} m")
        return self


class SensorSpec(StrictModel):
    """Sensor imperfections (white noise, constant bias, rounding)."""

    accel_noise: float = Field(default=0.005, ge=0, le=1, description="m/s² RMS")
    gyro_noise: float = Field(default=1e-4, ge=0, le=0.1, description="rad/s RMS")
    accel_bias: float = Field(default=0.02, ge=-1, le=1, description="m/s²")
    gyro_bias: float = Field(default=2e-4, ge=-0.1, le=0.1, description="rad/s")
    digits: int | None = Field(default=8, ge=3, le=17, description="Significant digits kept")


class IrregularitySpec(StrictModel):
    """Unloaded rail geometry: a random profile of a standard spectrum (1-120 m wavelengths)."""

    spectrum: str = Field(
        max_length=40,
        description="Spectrum name (their sources: GET /api/v1/simulate/spectra)",
        json_schema_extra=closed_list(SPECTRA),
    )
    seed: int = Field(
        default=0, ge=0, le=2**31 - 1,
        description="Seed of the profile (and of the support scatter): the same seed is the "
        "same physical track",
    )  # fmt: skip


class SimulateRequest(StrictModel):
    """A synthetic run: a track with soft zones (straight, or with the rail geometry of a
    standard spectrum), the vehicle at constant speed."""

    track: Name | None = Field(
        default=None,
        description="Track to store the run on (default: a track of its own per simulated "
        "physical track — rail, length, zones, support scatter and seed —, named after it, "
        "e.g. 'simulated straight 500 m, seed 0, 2 zones [3fa2c1]'; never mixed with real runs)",
    )
    vehicle: Name | None = Field(default=None, description="Vehicle name (default table1)")
    name: Name | None = None
    length_m: float = Field(default=500.0, ge=80, le=5000, description="Track length, m")
    speed_mps: float = Field(default=22.0, ge=5, le=80, description="Speed, m/s")
    zones: list[ZoneSpec] = Field(
        default_factory=lambda: [
            ZoneSpec(start_m=140, end_m=146, loss=0.5),
            ZoneSpec(start_m=333, end_m=337, loss=0.35),
        ],
        max_length=50,
        description="Soft zones; also accepts 'start:end:loss' strings",
    )
    start_chainage_m: float = Field(
        default=24.13, ge=0, le=CHAINAGE_LIMIT_M, allow_inf_nan=False,
        description="Body-centre start chainage, m",
    )  # fmt: skip
    direction: Direction = "increasing"
    sensor: SensorSpec | Literal["ideal", "realistic"] = Field(
        default="realistic",
        description="'ideal' (exact signals), 'realistic' (the accuracy requirement's noise) "
        "or explicit noise figures",
    )
    sensor_grade: str | None = Field(
        default=None,
        max_length=40,
        description="An IMU class instead of `sensor`: "
        + "; ".join(f"{k}: {g.label}" for k, g in SENSOR_GRADES.items())
        + " (noise densities, per-pass bias drawn from the seed, bias wander, quantisation, "
        "jitter; GET /api/v1/simulate/sensor-grades). Null: `sensor` applies",
        json_schema_extra={"enum": [*SENSOR_GRADES, None], "x-values": list(SENSOR_GRADES)},
    )
    jitter: float = Field(
        default=0.05, ge=0, le=0.3, description="Support stiffness scatter (0.05 = ±5 %)"
    )
    seed: int = Field(default=0, ge=0, le=2**31 - 1)
    recorded_at: Timestamp | None = None
    irregularity: IrregularitySpec | None = Field(
        default=None, description="Rail geometry (null: a straight rail, the paper's case)"
    )

    @field_validator("sensor_grade")
    @classmethod
    def _known_grade(cls, grade: str | None) -> str | None:
        if grade is not None and grade not in SENSOR_GRADES:
            choices = ", ".join(SENSOR_GRADES)
            raise ValueError(f"unknown sensor grade {grade!r}; expected one of {choices}")
        return grade

    @field_validator("zones")
    @classmethod
    def _zones_sorted(cls, zones: list[ZoneSpec]) -> list[ZoneSpec]:
        return sorted(zones, key=lambda z: z.start_m)

    def simulated_track_name(self) -> str:
        """The default track of this simulation: one per physical track simulated (rail
        geometry, length, zones, support scatter, seed), so runs over the same simulated track
        meet and nothing simulated mixes with a real track's runs."""
        physical = {
            "length_m": self.length_m, "jitter": self.jitter, "seed": self.seed,
            "zones": [z.model_dump() for z in self.zones],
            "irregularity": None if self.irregularity is None else self.irregularity.model_dump(),
        }  # fmt: skip
        tag = hashlib.sha256(json.dumps(physical, sort_keys=True).encode()).hexdigest()[:6]
        rail = (
            "straight"
            if self.irregularity is None
            else f"{self.irregularity.spectrum} rail seed {self.irregularity.seed}"
        )
        n = len(self.zones)
        return (
            f"simulated {rail} {self.length_m:g} m, seed {self.seed}, "
            f"{n} zone{'s' if n != 1 else ''} [{tag}]"
        )


class TruthPublic(BaseModel):
    """What was simulated: the zones and the true loaded level (mm, static deflection included)."""

    zones: list[ZoneSpec]
    chainage_m: list[float]
    level_mm: list[float | None] = Field(
        description="True fused loaded level, mm, positive up (compare after removing a "
        "baseline: the engine's profile is band-limited)"
    )
    baseline_mm: list[float | None] = Field(
        description="The true level's baseline as soft-spot detection draws it (running median "
        "then mean over baseline_window_m), mm; the run's own is in its profile views"
    )
    baseline_window_m: float = Field(description="Length of the baseline's running median, m")


class SimulatePublic(BaseModel):
    """The stored synthetic run and its truth."""

    run: RunCreated
    truth: TruthPublic
