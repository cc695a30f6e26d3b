"""Geometry vs stiffness schemas: a track's separated stiffness and its reference surveys.

Chainage in m (aligned), geometry in mm, compliance in mm/kN, forces in N, ``k_rel`` the
support stiffness relative to the track's nominal (1 = nominal), losses in %.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, Field, field_validator, model_validator

from .common import (
    PROVISIONAL_DOC,
    PROVISIONAL_REASON_DOC,
    AlignmentStatus,
    Name,
    StrictModel,
)


class SeparatedSpotPublic(BaseModel):
    """A soft spot found by separating geometry and stiffness across passes."""

    start_m: float
    end_m: float
    peak_m: float
    stiffness_loss_pct: float = Field(description="Loss of support stiffness against nominal, %")
    depth_mm: float | None = Field(
        description="The compliance dip as a level dip under the engine's reference wheel load, mm"
    )
    loss_lo_pct: float | None = Field(description="Lower end of the loss's band, %")
    loss_hi_pct: float | None = Field(description="Upper end of the loss's band, %")
    confidence: float | None = Field(description="Confidence the loss is real (0-1)")
    basis: Literal["separated"] = "separated"
    provisional: bool = Field(default=False, description=PROVISIONAL_DOC)
    provisional_reason: str | None = Field(default=None, description=PROVISIONAL_REASON_DOC)


class ContributorPublic(BaseModel):
    """A pass that took part in the separation of the window."""

    kind: Literal["run", "survey"]
    id: int
    label: str
    mean_force_n: float = Field(description="Mean wheel force over the window, N")
    points: int = Field(description="Grid points of the window it covers")
    vehicle: str | None = Field(default=None, description="The run's vehicle (runs)")


class NotSeparablePublic(BaseModel):
    """A stretch where geometry and stiffness are not separable, and why."""

    from_m: float = Field(description="Start, m (aligned)")
    to_m: float = Field(description="End, m (aligned, inclusive)")
    reason: Literal["load", "precision"] = Field(
        description="load: the passes there have one wheel load (a pass with another load, "
        "or a survey, would separate it); precision: their levels are too uncertain (near "
        "the ends of runs, or too few passes)"
    )


class StiffnessPublic(BaseModel):
    """A track's separated geometry and support stiffness over a window (0.25 m grid).

    Where a point is not separable (``separable_at`` false) its geometry and stiffness are
    null: one wheel load cannot tell a geometric dip from a soft support.
    """

    track_id: int
    track: str
    from_m: float | None
    to_m: float | None
    grid_step_m: float
    k_nominal_n_per_m: float = Field(description="The track's nominal support stiffness, N/m")
    n: int = Field(description="Grid points some pass covers in the window")
    separable: bool = Field(description="True when part of the window is separable")
    separable_fraction: float = Field(description="Share of the covered points separable, 0-1")
    message: str | None = Field(
        description="Where the window is not separable (chainages in km+m) and what would make "
        "it separable, as sentences; null where the separation holds everywhere"
    )
    not_separable: list[NotSeparablePublic] = Field(
        default_factory=list,
        description="The stretches that are not separable, in order",
    )
    updating: bool = Field(
        description="A run stored a moment ago covers part of the window and its separation "
        "is being redone: this is the state before it; read again in a few seconds"
    )
    chainage_m: list[float]
    k_rel: list[float | None] = Field(description="Support stiffness / nominal")
    k_rel_lo: list[float | None] = Field(description="Lower end of k_rel's band")
    k_rel_hi: list[float | None] = Field(description="Upper end of k_rel's band")
    geometry_mm: list[float | None] = Field(description="Unloaded rail geometry, mm")
    geometry_sd_mm: list[float | None] = Field(description="Uncertainty of the geometry, mm")
    compliance_mm_per_kn: list[float | None] = Field(description="Track compliance, mm/kN")
    n_passes: list[int] = Field(description="Passes covering the point")
    load_ratio: list[float | None] = Field(description="Largest / smallest wheel force there")
    separable_at: list[bool] = Field(description="Whether the point is separable")
    provisional: bool = Field(
        default=False, description=PROVISIONAL_DOC + " (over the window's contributing passes)"
    )
    provisional_reason: str | None = Field(default=None, description=PROVISIONAL_REASON_DOC)
    soft_spots: list[SeparatedSpotPublic]
    contributors: list[ContributorPublic]


class SurveyFields(StrictModel):
    """What comes with a survey file: its wheel load and wavelength band."""

    wheel_load_n: float = Field(
        gt=1_000, le=500_000, allow_inf_nan=False,
        description="Static wheel load of the recording car during the survey, N",
    )  # fmt: skip
    band_min_m: float = Field(
        default=3.0, gt=0, le=100, allow_inf_nan=False,
        description="Shortest wavelength the survey's level holds, m (EN 13848 D1: 3)",
    )  # fmt: skip
    band_max_m: float = Field(
        default=25.0, gt=0, le=200, allow_inf_nan=False,
        description="Longest wavelength the survey's level holds, m (D1: 25, D2: 70)",
    )  # fmt: skip
    name: Name | None = None
    recorded_at: datetime | None = Field(default=None, description="When it was recorded")

    @model_validator(mode="before")
    @classmethod
    def _blank_is_unset(cls, data: Any) -> Any:
        # a blank form field is an unset option; the survey itself (csv) is never an option
        if isinstance(data, dict):
            return {
                k: v for k, v in data.items()
                if k not in SurveyFields.model_fields or not (isinstance(v, str) and not v.strip())
            }  # fmt: skip
        return data

    @model_validator(mode="after")
    def _band(self) -> SurveyFields:
        if self.band_max_m <= self.band_min_m:
            raise ValueError(
                f"band_max_m ({self.band_max_m} m) must be above band_min_m ({self.band_min_m} m)"
            )
        return self


class SurveyCreateJson(SurveyFields):
    """JSON body of ``POST /tracks/{track}/surveys``: the fields and the CSV text."""

    csv: str = Field(description="The survey as CSV text: chainage_m,level_mm")
    filename: str | None = Field(default=None, max_length=255)

    @field_validator("csv")
    @classmethod
    def _not_empty(cls, v: str) -> str:
        if not v.strip():
            raise ValueError(
                "the survey CSV is empty: give its text, a header chainage_m,level_mm and rows"
            )
        return v


class SurveyPublic(BaseModel):
    """A stored reference survey."""

    id: int
    track_id: int
    name: str | None
    original_filename: str | None
    recorded_at: datetime | None
    created_at: datetime
    wheel_load_n: float
    band_min_m: float
    band_max_m: float
    n_points: int
    chainage_min_m: float = Field(description="Start, m (aligned)")
    chainage_max_m: float = Field(description="End, m (aligned)")
    chainage_offset_m: float
    alignment_status: AlignmentStatus
    alignment_correlation: float | None
    alignment_reason: str | None
    duplicate: bool = Field(default=False, description="True when the same file was stored")
