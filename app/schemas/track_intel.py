"""Track intelligence schemas: aggregated profile, defect register, alerts, limits.

Chainage in m (aligned), levels and depths in mm, stiffness loss in %, trends per month
(30.44 days).
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field

from app.services.track.aggregate import NEWEST_PASSES
from engine.register import SOURCES, Limits

from .common import PROVISIONAL_DOC, PROVISIONAL_REASON_DOC, StrictModel

DefectStatus = Literal["new", "confirmed", "worsening", "stable"]
LimitLevel = Literal["immediate", "intervention", "alert"]

_DEFAULTS = Limits()


class TrackProfileAggregatePublic(BaseModel):
    """A track's aggregated profile over its aligned runs, one value per 0.25 m grid point."""

    track_id: int
    track: str = Field(description="Track name")
    from_m: float | None = Field(description="Window asked for, m (null: the start)")
    to_m: float | None = Field(description="Window asked for, m (null: the end)")
    grid_step_m: float = Field(description="Grid step of the aggregate, m")
    n: int = Field(description="Grid points with data in the window")
    decimated: bool = Field(
        description="True when max_points thinned the answer (each bucket keeps its lowest and "
        "highest point)"
    )
    chainage_m: list[float] = Field(description="Aligned chainage, m")
    level_mm: list[float] = Field(
        description=f"Median level over the newest (at most {NEWEST_PASSES}) aligned runs "
        "covering the point, mm"
    )
    spread_mm: list[float] = Field(description="Robust spread (1.4826 x MAD) of the runs, mm")
    n_runs: list[int] = Field(description="Aligned runs in the point's median")


SightingSource = Literal["pass", "separated", "aggregate", "isolated"]
"""The kinds of sighting (``engine.register.SOURCES``; checked at import)."""
if set(get_args(SightingSource)) != set(SOURCES):  # pragma: no cover - a developer's slip
    raise RuntimeError("SightingSource must list engine.register.SOURCES")


class DefectObservationPublic(BaseModel):
    """One sighting of a defect (aligned chainage): one run's, or the separation's."""

    run_id: int = Field(description="The run (for a separated spot: its earliest pass)")
    recorded_at: datetime = Field(
        description="When the run was recorded (else uploaded); for a separated spot, the "
        "recording time of the pass that brought its passes to two wheel loads"
    )
    start_m: float
    end_m: float
    peak_m: float
    depth_mm: float
    stiffness_loss_pct: float | None
    source: SightingSource = Field(
        description="pass (one run), separated, aggregate, isolated (one pass's EN 13848 level "
        "at an isolated defect)"
    )
    passes: list[str] = Field(description="The passes behind it: 'run 12', 'survey 3'")
    loss_lo_pct: float | None = Field(description="Band of the loss, % (separated)")
    loss_hi_pct: float | None = None
    level: LimitLevel | None = Field(
        default=None,
        description="The limit level this sighting reached by limits of its own (isolated "
        "defects: the line speed's EN 13848 class); null for soft spots",
    )


class DefectEvidencePublic(BaseModel):
    """One kind of sighting behind a defect."""

    kind: SightingSource = Field(
        description="pass: single runs' detections; separated: the track's geometry/stiffness "
        "separation across wheel loads; aggregate: the many-pass aggregate"
    )
    passes: int = Field(description="Distinct passes (runs, surveys) behind these sightings")
    loads: int = Field(description="Distinct wheel loads among them (10 % apart or more)")
    sightings: int = Field(description="Sightings of this kind")
    first_seen: datetime = Field(description="Recording time of the earliest of those passes")
    last_seen: datetime = Field(description="Recording time of the latest")
    text: str = Field(description="As a person reads it: 'separated: 4 passes, 2 loads'")


class DefectPublic(BaseModel):
    """A tracked defect of the soft-spot register: soft spots of many runs at one place."""

    id: str = Field(description="Stable id: the first run that saw it and where")
    priority: int = Field(
        description="1 immediate action, 2 intervention, 3 alert, 4 below the limits"
    )
    level: LimitLevel | None = Field(description="Most urgent limit reached by the latest run")
    level_since: datetime | None = Field(
        description="Recording time of the first run that reached today's level (or worse)"
    )
    status: DefectStatus = Field(
        description="new (one pass supports it), confirmed (independent passes support it, "
        "too few successive sightings for a trend), worsening (significant growth of depth or "
        "stiffness loss), stable"
    )
    start_m: float = Field(description="Start, m (median over the runs that saw it)")
    end_m: float = Field(description="End, m (median)")
    peak_m: float = Field(description="Deepest point, m (median)")
    source: SightingSource = Field(
        description="The kind of evidence its figures come from (the most trusted present: "
        "separated, then aggregate, then pass); isolated: a D1/D2 level over the speed-class "
        "limits (depth_mm its mean-to-peak value, level by those limits)"
    )
    depth_mm: float = Field(
        description="Depth in the latest sighting, mm; for a separated spot the dip the "
        "softened support causes under the reference wheel load (100 kN)"
    )
    stiffness_loss_pct: float | None = Field(description="Stiffness loss in the latest sighting, %")
    stiffness_loss_lo_pct: float | None = Field(description="Band of the loss, low end, %")
    stiffness_loss_hi_pct: float | None = Field(description="Band of the loss, high end, %")
    evidence: list[DefectEvidencePublic] = Field(
        description="What supports it, most trusted kind first"
    )
    evidence_text: str = Field(
        description="The evidence as one line: 'separated: 4 passes, 2 loads'"
    )
    trend_mm_per_month: float = Field(description="Depth trend (least squares), mm/month")
    trend_loss_pct_per_month: float = Field(
        description="Stiffness-loss trend, percentage points/month"
    )
    first_seen: datetime = Field(description="Recording time of the earliest supporting pass")
    last_seen: datetime = Field(description="Recording time of the latest supporting pass")
    runs_seen: int = Field(description="Passes that support it (every kind of evidence)")
    runs_covering: int = Field(description="Aligned runs whose profile covers it")
    history: list[DefectObservationPublic] | None = Field(
        default=None, description="Every run's sighting, oldest first (?include=history)"
    )
    stiffness_basis: Literal["separated", "single pass"] | None = Field(
        default=None,
        description="What the stiffness loss rests on: separated across passes of different "
        "wheel loads, or one pass over rail smooth at the noise level; null with no loss",
    )
    message: str | None = Field(
        default=None,
        description="Why no stiffness loss is given (one wheel load cannot tell geometry "
        "from stiffness here)",
    )
    provisional: bool = Field(default=False, description=PROVISIONAL_DOC)
    provisional_reason: str | None = Field(default=None, description=PROVISIONAL_REASON_DOC)
    next_limit: dict[str, Any] | None = Field(
        default=None,
        description="isolated: when the defect's passes, trended, reach its next level "
        "(level, limit_mm, date, earliest, latest, reached, slope_mm_per_year); else null",
    )


def _limit(default: float | None, unit: str, what: str) -> float | None:
    # a stiffness loss is a share of the nominal stiffness: at most all of it
    return Field(
        default=default,
        gt=0,
        le=100.0 if unit == "%" else None,
        allow_inf_nan=False,
        description=f"{what}, {unit} (null: not used; default {default})",
    )


class LimitsFields(StrictModel):
    """Limits of a track in the style of EN 13848 (alert, intervention, immediate action).

    A defect reaches a level when its depth *or* its stiffness loss reaches that level's
    value; each criterion must grow from alert to intervention to immediate. A field left out
    of a PUT takes its default; null switches that criterion off.
    """

    # strict: ``true`` is not a number (it was stored as 1.0), nor is the text "5"
    model_config = ConfigDict(extra="forbid", strict=True)

    alert_depth_mm: float | None = _limit(_DEFAULTS.alert_depth_mm, "mm", "Alert depth")
    intervention_depth_mm: float | None = _limit(
        _DEFAULTS.intervention_depth_mm, "mm", "Intervention depth"
    )
    immediate_depth_mm: float | None = _limit(
        _DEFAULTS.immediate_depth_mm, "mm", "Immediate-action depth"
    )
    alert_loss_pct: float | None = _limit(_DEFAULTS.alert_loss_pct, "%", "Alert stiffness loss")
    intervention_loss_pct: float | None = _limit(
        _DEFAULTS.intervention_loss_pct, "%", "Intervention stiffness loss"
    )
    immediate_loss_pct: float | None = _limit(
        _DEFAULTS.immediate_loss_pct, "%", "Immediate-action stiffness loss"
    )


class LimitsUpdate(LimitsFields):
    """Body of ``PUT /tracks/{track}/limits``."""


class LimitsPublic(LimitsFields):
    """A track's limits (its own, or the defaults)."""

    model_config = {"extra": "ignore"}

    track_id: int
    track: str = Field(description="Track name")
    is_default: bool = Field(description="True while the track has no limits of its own")
    updated_at: datetime | None = Field(description="When the limits were last set")
