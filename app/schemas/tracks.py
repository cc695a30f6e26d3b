"""Track schemas: a line's nominal rail and support properties (SI units)."""

from __future__ import annotations

from datetime import datetime
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from engine.track import TRACK_RANGES, TrackParams

from .common import StrictModel, UrlName


def _track_field(name: str) -> Any:
    """The pydantic field of a track parameter: the engine's default, unit and range."""
    lo, hi, unit, what = TRACK_RANGES[name]
    default = TrackParams.__dataclass_fields__[name].default
    return Field(default=default, ge=lo, le=hi, allow_inf_nan=False,
                 description=f"{what[0].upper()}{what[1:]}, {unit} ({lo:g} to {hi:g})")  # fmt: skip


class TrackParamsFields(BaseModel):
    """Nominal properties used by the stiffness-loss estimate (ranges: engine.track)."""

    k_nominal: float = _track_field("k_nominal")
    spacing: float = _track_field("spacing")
    EI: float = _track_field("EI")
    mass_per_m: float = _track_field("mass_per_m")
    c_support: float = _track_field("c_support")


class TrackCreate(TrackParamsFields, StrictModel):
    """A new track. Unspecified properties default to UIC60 on 80 kN/mm supports."""

    name: UrlName
    description: str | None = Field(default=None, max_length=2000)
    rail: str = Field(default="UIC60", min_length=1, max_length=50)


class TrackPublic(BaseModel):
    """A stored track (its parameters as stored: tracks made before the physical ranges were
    enforced are still shown)."""

    model_config = ConfigDict(from_attributes=True)

    k_nominal: float
    spacing: float
    EI: float
    mass_per_m: float
    c_support: float

    id: int
    name: str
    description: str | None
    rail: str
    created_at: datetime
    n_runs: int = Field(default=0, description="Number of runs stored on this track")
    has_centerline: bool = Field(
        default=False,
        description="Whether the track has a centerline (GET .../centerline answers 404 without)",
    )


class TracksPublic(BaseModel):
    """A page of tracks."""

    data: list[TrackPublic]
    count: int
