"""Track schemas: a line's nominal rail and support properties (SI units)."""

from __future__ import annotations

from datetime import datetime

from pydantic import BaseModel, ConfigDict, Field

from .common import StrictModel, UrlName

UIC60_EI = 210e9 * 3.055e-5


class TrackParamsFields(BaseModel):
    """Nominal properties used by the stiffness-loss estimate."""

    k_nominal: float = Field(
        default=8e7, gt=0, allow_inf_nan=False, description="Nominal support stiffness, N/m"
    )
    spacing: float = Field(
        default=0.6, gt=0, le=5, allow_inf_nan=False, description="Sleeper spacing, m"
    )
    EI: float = Field(
        default=UIC60_EI, gt=0, allow_inf_nan=False, description="Rail bending stiffness, N m²"
    )
    mass_per_m: float = Field(
        default=60.21, gt=0, allow_inf_nan=False, description="Rail mass per metre, kg/m"
    )
    c_support: float = Field(
        default=5e4, ge=0, allow_inf_nan=False, description="Support damping, N s/m"
    )


class TrackCreate(TrackParamsFields, StrictModel):
    """A new track. Unspecified properties default to UIC60 on 80 kN/mm supports."""

    name: UrlName
    description: str | None = Field(default=None, max_length=2000)
    rail: str = Field(default="UIC60", min_length=1, max_length=50)


class TrackPublic(TrackParamsFields):
    """A stored track."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    description: str | None
    rail: str
    created_at: datetime
    n_runs: int = Field(default=0, description="Number of runs stored on this track")


class TracksPublic(BaseModel):
    """A page of tracks."""

    data: list[TrackPublic]
    count: int
