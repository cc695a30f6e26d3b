"""Schemas of the dashboard's view endpoints (``/api/v1/views/...``).

These answers are shaped for drawing, not for storage: columnar arrays (one list per field),
decimated or binned server-side for the requested chainage window, so that a chart never
receives millions of points. Units: chainage in m, levels and depths in mm.
"""

from __future__ import annotations

from datetime import datetime

from pydantic import BaseModel, Field

from .common import PROVISIONAL_DOC, PROVISIONAL_REASON_DOC


class CsvPreviewPublic(BaseModel):
    """How the engine reads the head of a run log: columns, first rows, recognised mapping."""

    columns: list[str] = Field(description="Column names of the header line")
    rows: list[list[str]] = Field(description="First data rows as written")
    delimiter: str | None = Field(default=None, description="Field separator found")
    mapping: dict[str, str | None] = Field(
        description="Recognised column per role: time, accel, pitch_rate, speed, chainage"
    )
    units: dict[str, str | None] = Field(
        description="Recognised unit per role: time (s|ms|epoch_s), accel (m/s2|g), "
        "pitch_rate (rad/s|deg/s), speed (m/s|km/h)"
    )
    gravity: str | None = Field(default=None, description="'included' or 'removed' if known")
    warnings: list[str] = Field(
        default_factory=list,
        description="Problems that would stop the upload and assumptions worth checking",
    )
    recorded_at: datetime | None = Field(
        default=None,
        description="When the first sample was recorded (UTC), from a time column in epoch "
        "seconds or milliseconds; null when the times count from the start",
    )


class ProfileViewPublic(BaseModel):
    """A run's profile in a chainage window, min/max-decimated when longer than asked.

    With ``decimated`` each bucket of grid points gives two points (its lowest and highest
    value, in chainage order), so a dip stays visible at any zoom level.
    """

    run_id: int
    from_m: float = Field(description="Start of the window served, m (aligned chainage)")
    to_m: float = Field(description="End of the window served, m")
    n_points: int = Field(description="Grid points of the run in the window")
    decimated: bool
    chainage_m: list[float]
    level_mm: list[float | None]
    front_level_mm: list[float | None]
    rear_level_mm: list[float | None]
    baseline_mm: list[float | None]


class MapRunPublic(BaseModel):
    """One row of the chainage map: a processed run of the track."""

    id: int
    label: str = Field(description="Row label: recorded date and time (UTC) and run id")
    name: str | None = Field(description="The run's own label, if any (user text)")
    recorded_at: datetime | None
    vehicle: str
    chainage_min_m: float | None = Field(description="Aligned chainage, m")
    chainage_max_m: float | None
    chainage_offset_m: float
    n_soft_spots: int


class MapSpotsPublic(BaseModel):
    """Soft spots of the map's runs in the window, columnar; ``run_index`` points into runs."""

    run_index: list[int]
    run_id: list[int]
    start_m: list[float]
    end_m: list[float]
    peak_m: list[float]
    depth_mm: list[float]
    stiffness_loss_pct: list[float | None]


class HeatmapPublic(BaseModel):
    """Lowest loaded level per run (rows, in the order of ``runs``) and chainage bin, mm."""

    x: list[float] = Field(description="Bin centres, m")
    bin_m: float = Field(description="Bin width, m")
    z: list[list[float | None]] = Field(description="One row per run; null = no data")


class ZonePublic(BaseModel):
    """A zone of the chainage map: the defect register (``engine.register``, the one zone
    model) over the soft spots shown, also for runs that are not aligned. Spots overlapping or
    at most 1 m apart join; one sighting per run (its deepest)."""

    id: int = Field(description="Index of the zone in chainage order (not stable over time)")
    start_m: float = Field(description="Median start over the runs that saw it, m")
    end_m: float = Field(description="Median end over the runs that saw it, m")
    peak_m: float = Field(description="Median peak chainage of the member spots, m")
    runs_seen: int = Field(description="Passes that support the zone (every kind of evidence)")
    runs_total: int = Field(description="Map runs whose profile covers the zone")
    depth_mm: float = Field(description="Depth seen by the latest run that saw it, mm")
    depth_max_mm: float = Field(description="Deepest sighting, mm")
    stiffness_loss_pct: float | None = Field(description="Estimated loss seen by the latest run, %")
    severity: float = Field(
        description="Ranking key, mm: latest depth x share of covering runs that saw it"
    )
    first_seen: datetime | None
    last_seen: datetime | None
    run_ids: list[int] = Field(description="The runs behind it (every kind of evidence)")
    source: str = Field(
        default="pass",
        description="Kind of evidence its figures come from: pass (single runs), separated "
        "(the track's geometry/stiffness separation), aggregate",
    )
    evidence_text: str = Field(
        default="", description="Its evidence as one line: 'separated: 4 passes, 2 loads'"
    )
    provisional: bool = Field(default=False, description=PROVISIONAL_DOC)
    provisional_reason: str | None = Field(default=None, description=PROVISIONAL_REASON_DOC)


class MapTrackPublic(BaseModel):
    """The track of a chainage map: what the map's heading shows and the beam model needs."""

    id: int
    name: str
    description: str | None
    rail: str
    k_nominal: float = Field(description="Nominal support stiffness, N/m")
    spacing: float = Field(description="Support spacing, m")


class ChainageMapPublic(BaseModel):
    """Everything the track view draws for one chainage window."""

    track: MapTrackPublic
    chainage_min_m: float | None = Field(description="Extent of all map runs, m")
    chainage_max_m: float | None
    from_m: float | None = Field(description="Window asked for (null: whole track)")
    to_m: float | None
    runs: list[MapRunPublic] = Field(description="Processed runs, newest first")
    runs_omitted: int = Field(description="Older processed runs left out (max_runs)")
    runs_pending: int = Field(description="Runs of the track still processing or failed")
    spots: MapSpotsPublic | None
    zones: list[ZonePublic] | None
    heatmap: HeatmapPublic | None
    heatmap_note: str | None = Field(default=None, description="Why there is no heatmap")


class WindowRunPublic(BaseModel):
    """One run's fused profile inside a chainage window."""

    id: int
    label: str
    recorded_at: datetime | None
    wheel_load_n: float | None = Field(
        default=None,
        description="Mean wheel force of the run (else its declared static wheel load), N: "
        "passes of different loads are what tells a soft support from the rail's geometry",
    )
    vehicle: str | None = Field(default=None, description="Vehicle name")
    decimated: bool
    chainage_m: list[float]
    level_mm: list[float | None]


class WindowPublic(BaseModel):
    """Fused profiles of the processed runs of a track inside ``[from_m, to_m]``."""

    from_m: float
    to_m: float
    runs: list[WindowRunPublic] = Field(description="Runs covering the window, oldest first")
