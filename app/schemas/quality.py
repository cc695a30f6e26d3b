"""Track quality schemas (EN 13848): sections, isolated defects, line speeds, quality limits.

Chainage in m (aligned), levels and SDs in mm, speeds km/h, times UTC ISO 8601.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, Field

from .common import StrictModel

Basis = Literal["unloaded", "loaded", "mixed"]
Level = Literal["immediate", "intervention", "alert"]


class CrossingPublic(BaseModel):
    """When a trended value reaches the next limit (straight line through the passes)."""

    level: str = Field(description="The next level or class")
    limit_mm: float
    reached: bool
    slope_mm_per_year: float | None
    date: str | None = Field(description="The fit's crossing (null: not growing)")
    earliest: str | None = Field(description="Crossing of the 95 % band's steeper slope")
    latest: str | None = Field(description="Crossing of the 95 % band's flatter slope (null: "
                               "the band allows no growth)")  # fmt: skip


class QualitySectionPublic(BaseModel):
    """One section of the track (``section_m`` long, counted from chainage 0)."""

    start_m: float
    end_m: float
    d1_sd_mm: float | None = Field(description="SD of the D1 (3-25 m) level, mm")
    d2_sd_mm: float | None = Field(description="SD of the D2 level (band: d2_band_m), mm")
    coverage: float | None = Field(description="Share of the section with a level, 0-1")
    n_passes: int = Field(description="Aligned runs covering at least half of the section")
    last_pass: str | None
    days_since_last_pass: float | None
    repeatability_d1_mm: float | None = Field(
        description="95 % of |difference| between the passes' D1 levels, mm"
    )
    speed_kmh: float | None = Field(description="Line speed at the section's middle")
    quality_class: str | None = Field(description="A-E from the D1 SD and the speed class")
    basis: Basis = Field(description="unloaded: separated geometry; loaded: aggregated "
                         "loaded level; mixed: both")  # fmt: skip
    d2_level: Literal["long", "quality", "mixed"] = Field(
        description="The level D2 is filtered from: long: the passes' own 3-100 m loaded "
        "level (all of D2's 25-70 m); quality: the stored 3-40 m level (passes stored before "
        "the long level was kept: D2 holds only 25-40 m); mixed: both"
    )
    next_class: CrossingPublic | None = None


class QualityDefectPublic(BaseModel):
    """An isolated defect: a stretch where the filtered level reaches a limit."""

    peak_m: float
    start_m: float
    end_m: float
    band: str
    value_mm: float = Field(description="Mean-to-peak value at the peak, signed, mm")
    level: Level
    speed_kmh: float | None
    limits_mm: dict[str, float | None]
    basis: Literal["unloaded", "loaded"]
    next_limit: CrossingPublic | None = None


class QualityPublic(BaseModel):
    """A track's geometry quality in EN 13848 terms."""

    track_id: int
    track: str
    section_m: float
    filters: dict[str, dict[str, Any]]
    d2_band_m: list[float] = Field(description="Wavelengths D2 actually covers here, m")
    d2_waiting_runs: list[int] = Field(
        default_factory=list,
        description="Runs answered done moments ago whose long level (D2's) is still being "
        "inverted: D2 leaves them out until it is stored (ask again in a few seconds)",
    )
    notes: list[str]
    limits_default: bool
    unverified_limits: list[str] = Field(
        default_factory=list,
        description="Limit tables in use that are the product's defaults, not verified "
        "against EN 13848-5/-6 (isolated_mm.D1, isolated_mm.D2, class_sd_mm)",
    )
    limits_source: str | None = Field(
        default=None, description="What the unverified defaults rest on (null: none in use)"
    )
    sections: list[QualitySectionPublic]
    defects: list[QualityDefectPublic]
    repeatability: dict[str, Any] | None
    observability: list[dict[str, Any]] = Field(
        description="Per vehicle of the passes, at its median speed: wavelengths its axle "
        "spacing hides from bounce or pitch, and ranges neither signal carries (3-70 m)"
    )
    survey_comparison: list[dict[str, Any]]
    traces: dict[str, list[float | None]] | None = None


class LineSpeedRange(StrictModel):
    """A line speed over a chainage range."""

    from_m: float = Field(description="Start, m (aligned chainage)")
    to_m: float = Field(description="End, m (> from_m)")
    speed_kmh: float = Field(description="Line speed, km/h (0 < v <= 300)")


class LineSpeedsBody(StrictModel):
    """A track's line speeds (replaces the stored ones)."""

    ranges: list[LineSpeedRange] = Field(max_length=10_000)


class LineSpeedsPublic(BaseModel):
    """A track's line speeds, ordered by chainage."""

    track_id: int
    track: str
    ranges: list[LineSpeedRange]


class QualityLimitsBody(StrictModel):
    """A track's quality limits; a key left out takes its default."""

    isolated_mm: dict[str, list[list[float | None]]] | None = Field(
        default=None,
        description="band -> per speed class (<=80, <=120, <=160, <=230, <=300 km/h) "
        "[alert, intervention, immediate] mean-to-peak limits, mm",
    )
    class_sd_mm: list[list[float]] | None = Field(
        default=None, description="per speed class the upper D1 SD of classes A, B, C, D, mm"
    )


class QualityLimitsPublic(BaseModel):
    """A track's quality limits (or the defaults)."""

    track_id: int
    track: str
    is_default: bool
    speed_classes_kmh: list[float]
    isolated_mm: dict[str, list[list[float | None]]]
    class_sd_mm: list[list[float]]
