"""Run schemas: upload metadata and column/unit options, stored runs, profiles, soft spots."""

from __future__ import annotations

import dataclasses
import functools
from datetime import datetime
from typing import TYPE_CHECKING, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, create_model, model_validator
from pydantic.json_schema import JsonDict

from engine.logio import (
    GRAVITY_MODES,
    OPTION_UNITS,
    OPTIONAL_ROLES,
    ROLE_LABELS,
    UNIT_LABELS,
    CsvOptions,
)
from engine.plausibility import WHEEL_LOAD_MAX_N, WHEEL_LOAD_MIN_N
from engine.track import TRACK_RANGES

from .common import CHAINAGE_LIMIT_M, AlignmentStatus, Name, StrictModel, Timestamp

Direction = Literal["increasing", "decreasing"]


def _new_track_field(name: str) -> Any:
    """An optional property of a track the upload creates: the engine's unit and range."""
    lo, hi, unit, what = TRACK_RANGES[name]
    return Field(default=None, ge=lo, le=hi, allow_inf_nan=False,
                 description=f"New track only: {what}, {unit} ({lo:g} to {hi:g}); ignored "
                 "when the track exists")  # fmt: skip


NEW_TRACK_FIELDS = ("track_description", "track_rail", "track_k_nominal", "track_spacing")
"""Upload fields describing a track the upload creates (stored with the run, in one
transaction: a rejected upload leaves no track behind)."""
RunStatus = Literal["processing", "done", "failed"]
RunStage = Literal["queued", "inverting", "storing"]


def _csv_option(f: dataclasses.Field[Any]) -> Any:
    """The pydantic field of one ``CsvOptions`` field; unit fields carry their units
    (``x-units``, ``x-unit-labels``) so the dashboard builds its choices from the schema."""
    if f.name == "gravity":
        modes = ", ".join(GRAVITY_MODES)
        what = "whether the acceleration includes gravity"
        # (the reader also takes other letter cases: the enum states the documented spellings)
        modes_extra: JsonDict = {"x-values": list(GRAVITY_MODES), "enum": list(GRAVITY_MODES)}
        return (
            str,
            Field(default="auto", max_length=20, description=f"{modes}: {what}",
                  json_schema_extra=modes_extra),
        )  # fmt: skip
    role, kind = f.name.rsplit("_", 1)
    label = ROLE_LABELS[role]
    extra: JsonDict = {"x-role": role, "x-label": label}
    if role in OPTIONAL_ROLES:
        extra["x-optional"] = True
    if kind == "column":
        return (
            str | None,
            Field(
                default=None, min_length=1, max_length=200, json_schema_extra=extra,
                description=f"Name of the {label} column; unset: recognised from the header",
            ),
        )  # fmt: skip
    units = OPTION_UNITS[role]
    extra["x-units"] = list(units)
    extra["x-unit-labels"] = {u: UNIT_LABELS.get(u, u) for u in units}

    def unit_schema(schema: JsonDict) -> None:
        schema.update(extra)
        # the documented spellings (the reader also takes common others, e.g. m/s^2, kmh)
        alts = schema.get("anyOf")
        for alt in alts if isinstance(alts, list) else []:
            if isinstance(alt, dict) and alt.get("type") == "string":
                alt["enum"] = list(units)

    return (
        str | None,
        Field(
            default=None, max_length=20, json_schema_extra=unit_schema,
            description=f"Unit of the {label} column: {' or '.join(units)} (common spellings "
            "such as m/s^2, dps or kmh too); unset: from the column name/values",
        ),
    )  # fmt: skip


# One model per idea: the options are those of the engine's CsvOptions (names, units), so an
# option added to the reader appears in the API, the preview and the dashboard by itself.
if TYPE_CHECKING:

    class CsvOptionsFields(StrictModel):
        """Which column is which and in what unit (fields: those of ``CsvOptions``)."""

        gravity: str

else:
    CsvOptionsFields = create_model(
        "CsvOptionsFields",
        __base__=StrictModel,
        __doc__="Which column is which and in what unit (unset: recognised from the header). "
        "Units are checked by the CSV reader, which also takes common spellings; an "
        "unsupported unit is answered 422 naming the field.",
        **{f.name: _csv_option(f) for f in dataclasses.fields(CsvOptions)},
    )


class RunMetadata(StrictModel):
    """What comes with a run log: where, with what vehicle, when."""

    track: Name | None = Field(
        default=None, description="Track name; a new name creates the track (UIC60, 80 kN/mm)"
    )
    track_id: int | None = Field(
        default=None, ge=1, description="Existing track id (instead of track)"
    )
    vehicle: Name | None = Field(
        default=None, description="Vehicle name (default: table1, the paper's Table 1 vehicle)"
    )
    vehicle_id: int | None = Field(default=None, ge=1, description="Existing vehicle id")
    name: Name | None = Field(default=None, description="Optional label of the run")
    start_chainage_m: float | None = Field(
        default=None,
        allow_inf_nan=False,
        ge=-CHAINAGE_LIMIT_M,
        le=CHAINAGE_LIMIT_M,
        description="Chainage of the body centre at the first sample, m (required without a "
        "chainage column)",
    )
    direction: Direction = "increasing"
    recorded_at: Timestamp | None = Field(
        default=None, description="When the run was recorded (ISO 8601; UTC if no offset)"
    )
    track_description: str | None = Field(
        default=None, max_length=2000, description="New track only: its description"
    )
    track_rail: str | None = Field(
        default=None, min_length=1, max_length=50, description="New track only: rail (UIC60)"
    )
    track_k_nominal: float | None = _new_track_field("k_nominal")
    track_spacing: float | None = _new_track_field("spacing")
    payload_kg: float | None = Field(
        default=None, ge=0, le=200_000, allow_inf_nan=False,
        description="Payload carried on top of the vehicle's registered body mass, kg "
        "(passengers, freight); sets the static wheel load the run is inverted with",
    )  # fmt: skip
    static_wheel_load_n: float | None = Field(
        default=None, ge=WHEEL_LOAD_MIN_N, le=WHEEL_LOAD_MAX_N, allow_inf_nan=False,
        description="Measured static wheel load during the run (mean of the axles), N; "
        "instead of payload_kg. Unset: the median of the log's load-weigh column if it has one",
    )  # fmt: skip

    @model_validator(mode="after")
    def _one_track_one_vehicle(self) -> RunMetadata:
        if self.track is None and self.track_id is None:
            raise ValueError("give the track (its name; a new name creates it) or track_id")
        if self.track is not None and self.track_id is not None:
            raise ValueError("give either track (name) or track_id, not both")
        if self.vehicle is not None and self.vehicle_id is not None:
            raise ValueError("give either vehicle (name) or vehicle_id, not both")
        if self.payload_kg is not None and self.static_wheel_load_n is not None:
            raise ValueError("give either payload_kg or static_wheel_load_n, not both")
        return self

    def new_track(self) -> dict[str, Any]:
        """The properties given for a track this upload creates (unset ones left out), as
        ``Track`` columns (description, rail, k_nominal, spacing)."""
        return {
            name.removeprefix("track_"): getattr(self, name)
            for name in NEW_TRACK_FIELDS
            if getattr(self, name) is not None
        }


@functools.cache
def _free_text_fields(model: type[BaseModel]) -> frozenset[str]:
    """Fields of ``model`` that take any text (no enum or format): the text ``null`` is a
    value there."""

    def free(schema: Any) -> bool:
        return (
            isinstance(schema, dict)
            and schema.get("type") == "string"
            and not ({"enum", "format", "const"} & schema.keys())
        )

    return frozenset(
        name
        for name, prop in model.model_json_schema()["properties"].items()
        if free(prop) or any(free(alt) for alt in prop.get("anyOf", ()))
    )


class RunUploadForm(CsvOptionsFields, RunMetadata):
    """Form fields of a multipart upload (besides ``file``). Empty fields count as unset."""

    @model_validator(mode="before")
    @classmethod
    def _blank_is_unset(cls, data: Any) -> Any:
        if isinstance(data, dict):
            return {k: v for k, v in data.items() if not (isinstance(v, str) and not v.strip())}
        return data

    @classmethod
    def from_form(cls, fields: dict[str, Any]) -> dict[str, Any]:
        """The multipart fields as this form reads them: ``null`` on a field that is not free
        text (a number, id, unit, date, direction) is unset, as an empty field is. A form
        has no null, and HTTP clients write an unset value as the text ``null`` (on a name
        it stays a name)."""
        text = _free_text_fields(cls)
        return {k: v for k, v in fields.items() if not (v == "null" and k not in text)}

    def csv_options(self) -> dict[str, Any]:
        """The column/unit options that were set."""
        return {
            k: getattr(self, k)
            for k in CsvOptionsFields.model_fields
            if getattr(self, k) is not None
        }


class RunColumns(StrictModel):
    """A log as canonical SI columns of equal length."""

    time_s: list[float] = Field(description="Sample times, s, strictly increasing")
    accel_z_mps2: list[float] = Field(description="Vertical body acceleration, m/s², no gravity")
    pitch_rate_radps: list[float] = Field(description="Body pitch rate, rad/s, nose-up positive")
    speed_mps: list[float] | None = Field(default=None, description="Speed, m/s")
    chainage_m: list[float] | None = Field(default=None, description="Body-centre chainage, m")
    wheel_load_n: list[float] | None = Field(
        default=None,
        description="Static wheel load from a load-weigh system, N (its median is the run's "
        "static_wheel_load_n unless that or payload_kg is given)",
    )


class RunCreateJson(RunUploadForm):
    """JSON body of ``POST /api/v1/runs``: the metadata and either ``csv`` or ``columns``.

    ``csv`` carries the file's text and is read exactly like an upload (the column/unit
    options apply); ``columns`` carries canonical SI arrays and takes no options.
    """

    csv: str | None = Field(default=None, description="The run log as CSV text")
    columns: RunColumns | None = None
    filename: str | None = Field(default=None, max_length=255, description="Kept as data only")

    @model_validator(mode="after")
    def _one_payload(self) -> RunCreateJson:
        if (self.csv is None) == (self.columns is None):
            raise ValueError("give exactly one of csv (CSV text) or columns (SI arrays)")
        if self.columns is not None and self.csv_options() != {"gravity": "auto"}:
            raise ValueError("column/unit options apply to csv only; columns are canonical SI")
        return self


class RunError(BaseModel):
    """Why a run failed."""

    model_config = ConfigDict(extra="allow")

    message: str
    column: str | None = None
    row: int | None = None
    kind: str | None = None


class RunAlignmentPublic(BaseModel):
    """How a processed run was placed on its track's chainage (issue 6)."""

    status: AlignmentStatus = Field(
        description="reference (first data on its stretch, offset 0), aligned (offset found by "
        "cross-correlation with the track's aggregated profile), placed (no trustworthy "
        "match yet: joined the track's aggregate and register at its logged chainage, aligned "
        "again as the track gains passes) or unaligned (no profile to place)"
    )
    offset_m: float = Field(description="Offset added to the run's logged chainage, m")
    correlation: float | None = Field(
        description="Normalised correlation with the track's profile at that offset (-1..1)"
    )
    overlap_m: float | None = Field(description="Track length compared at that offset, m")
    reason: str | None = Field(description="Why the run is a reference or is unaligned")


class RunPositioningPublic(BaseModel):
    """How a run was placed by its GNSS fixes on the track's centerline (issue 11)."""

    method: Literal["gnss"] = "gnss"
    start_chainage_m: float = Field(description="Fitted chainage of the first sample, m")
    direction: Direction
    scale: float = Field(description="Odometer scale factor found (true / logged distance)")
    residual_rms_m: float = Field(description="RMS of the fit's residuals over the fixes used, m")
    n_fixes: int = Field(description="Fixes in the log")
    n_considered: int | None = Field(
        default=None,
        description="Fixes projected onto the line: those of the log thinned to at most 10 a "
        "second (GNSS receivers give no more; None: placed before thinning existed)",
    )
    n_used: int = Field(description="Fixes the fit used")
    n_rejected: int = Field(description="Fixes considered that were off the line or outliers")
    offset_median_m: float = Field(description="Median distance of the fixes used from the line, m")
    offset_p95_m: float = Field(description="95th percentile of that distance, m")
    lateral_offset_m: float | None = Field(
        default=None,
        description="Median signed lateral offset of the fixes used, m: positive left of the "
        "line, negative right of it, looking towards increasing chainage. A run whose offset "
        "exceeds 3 m is refused as being on a neighbouring track (None: placed before this "
        "was recorded)",
    )
    pieces: int = Field(description="Pieces of the piecewise-linear odometer fit")
    knots_m: list[float] = Field(description="Odometer distances where the scale changes, m")


class DetectionLimitPublic(BaseModel):
    """What one pass could see: the smallest stiffness loss its detector finds per zone length.

    A zone that weak makes a dip as deep as the pass's detection threshold (found about half
    the time); weaker zones are not seen. The threshold is the detector's own (5 robust
    standard deviations of the pass's residual profile, at least 0.06 mm): the sensor noise
    the inversion measured, and rail geometry where the rail has it.
    """

    zone_length_m: list[float] = Field(description="Zone lengths, m")
    min_loss_pct: list[float | None] = Field(
        description="Smallest detectable stiffness loss for each length, % of nominal; null "
        "where even a 95 % loss would not reach the threshold"
    )
    threshold_mm: float = Field(description="The pass's detection threshold (dip depth), mm")


class RunPublic(BaseModel):
    """A stored run: metadata, processing state, quality indicators."""

    id: int
    name: str | None
    track_id: int
    track: str = Field(description="Track name")
    vehicle_id: int
    vehicle: str = Field(description="Vehicle name")
    vehicle_version: int | None = Field(
        default=None,
        description="Vehicle parameter version its results were computed with (None: not "
        "processed yet, or processed before versions existed)",
    )
    source: str = Field(description="upload, json or simulate")
    original_filename: str | None
    recorded_at: datetime | None
    created_at: datetime
    processed_at: datetime | None
    start_chainage_m: float | None
    direction: Direction
    sample_rate_hz: float
    n_samples: int
    duration_s: float
    speed_min_mps: float
    speed_max_mps: float
    chainage_min_m: float | None = Field(description="Start of the stored profile, m (aligned)")
    chainage_max_m: float | None = Field(description="End of the stored profile, m (aligned)")
    chainage_offset_m: float = Field(
        description="Offset added to the run's own chainage to align it with the track, m"
    )
    alignment: RunAlignmentPublic | None = Field(
        default=None, description="Alignment to the track (null until processed)"
    )
    status: RunStatus
    stage: RunStage | None = Field(description="While processing: queued, inverting, storing")
    progress: float = Field(ge=0, le=1, description="Rough processing progress, 0-1")
    error: RunError | None
    quality: dict[str, float | None] | None
    method: str | None
    n_soft_spots: int | None
    processing_s: float | None = Field(description="Inversion + detection time, s")
    payload_kg: float | None = Field(default=None, description="Declared payload, kg")
    static_wheel_load_n: float | None = Field(
        default=None, description="Declared static wheel load, N"
    )
    mean_wheel_force_n: float | None = Field(
        default=None, description="Mean force per wheel under the profile (static + dynamic), N"
    )
    stiffness_basis: Literal["single pass", "not separable"] | None = Field(
        default=None,
        description="What the run's own stiffness-loss figures rest on: 'single pass' when "
        "the rail is smooth at the noise level (they are valid), 'not separable' when rail "
        "geometry could have made its dips (no figure is given; see the track's stiffness)",
    )
    stiffness_message: str | None = Field(
        default=None, description="Plain words when the run's dips cannot be read as stiffness"
    )
    detection_limit: DetectionLimitPublic | None = Field(
        default=None,
        description="What this pass could see: the smallest stiffness loss it can detect "
        "for 3 m and 6 m zones, from its own noise (null until processed)",
    )
    content_hash: str
    options: dict[str, Any]
    positioning: RunPositioningPublic | None = Field(
        default=None,
        description="Placement by GNSS fixes on the track's centerline (null: placed by the "
        "start chainage given)",
    )
    detail_expired_at: datetime | None = Field(
        default=None,
        description="When the retention policy removed the run's detail (profile, signals, "
        "log: their routes answer 410 since); null while it is kept. Metadata and soft spots "
        "are kept for ever",
    )


class RunCreated(RunPublic):
    """Answer of an upload: the run, and whether it was already stored."""

    duplicate: bool = Field(
        default=False,
        description="True when the same log (its content, whatever the options sent with it) "
        "or the same Idempotency-Key was stored before: the stored run answers, nothing new is "
        "stored (a log is one pass)",
    )
    ignored: list[str] = Field(
        default_factory=list,
        description="On a duplicate: the fields this upload asked differently from how the "
        "stored run was read and placed; they were not applied",
    )
    note: str | None = Field(
        default=None,
        description="On a duplicate with ignored fields: what happened and how to read the "
        "log differently (delete the run, upload again)",
    )


class RunsPublic(BaseModel):
    """A page of runs, newest first."""

    data: list[RunPublic]
    count: int = Field(description="Runs matching the filter (all pages)")


class ProfilePublic(BaseModel):
    """A run's loaded profile on its chainage grid (mm, positive up; null = no data)."""

    run_id: int
    chainage_offset_m: float = Field(description="Offset included in chainage_m, m")
    n: int = Field(description="Number of grid points")
    chainage_m: list[float] = Field(description="Chainage, m (regular grid, aligned)")
    level_mm: list[float | None] = Field(description="Fused loaded level, mm")
    front_level_mm: list[float | None] | None = Field(
        default=None, description="Front-axle level, mm (with ?include=)"
    )
    rear_level_mm: list[float | None] | None = Field(
        default=None, description="Rear-axle level, mm (with ?include=)"
    )
    baseline_mm: list[float | None] | None = Field(
        default=None, description="Baseline the dips are measured from, mm (with ?include=)"
    )
    front_force_n: list[float | None] | None = Field(
        default=None, description="Front-axle wheel force, static + dynamic, N (with ?include=)"
    )
    rear_force_n: list[float | None] | None = Field(
        default=None, description="Rear-axle wheel force, static + dynamic, N (with ?include=)"
    )


class SoftSpotPublic(BaseModel):
    """A soft spot: extent and peak chainage (m), depth (mm), stiffness loss (%).

    The loss is given only where one pass can tell it (``stiffness_basis`` "single pass":
    the rail is smooth at the noise level); elsewhere it is null and ``message`` says why.
    """

    start_m: float
    end_m: float
    peak_m: float
    depth_mm: float
    stiffness_loss_pct: float | None
    stiffness_basis: Literal["single pass"] | None = None
    message: str | None = None


class SignalsPublic(BaseModel):
    """The run's raw signals against time, decimated to a few thousand points."""

    run_id: int
    n_samples: int
    decimated: bool
    time_s: list[float | None] = Field(description="Time from the first sample, s")
    accel_z_mps2: list[float | None]
    pitch_rate_radps: list[float | None]
    speed_mps: list[float | None]
