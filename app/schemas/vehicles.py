"""Vehicle schemas: the parameter set of each vehicle kind (SI units; the engine's
``VehicleParams`` for the half car, ``BogieParams`` for a bogie vehicle)."""

from __future__ import annotations

import dataclasses
from datetime import datetime
from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    ValidatorFunctionWrapHandler,
    create_model,
    field_validator,
    model_validator,
)

from engine.bogie import BogieParams
from engine.calibration import DEFAULT_FIT_BY_KIND, FITTABLE
from engine.vehicle import SENSOR_X_LIMIT_M, VehicleParams
from engine.vehicle_kinds import KIND_PRESETS

from .common import StrictModel, UrlName, closed_list


def _schema_field(f: dataclasses.Field[Any]) -> Any:
    """The pydantic field of one ``VehicleParams`` field: same default, unit and range."""
    unit, kind, what = f.metadata["unit"], f.metadata["kind"], f.metadata["description"]
    ranges: dict[str, dict[str, Any]] = {
        "positive": {"gt": 0.0},
        "nonnegative": {"ge": 0.0},
        "position": {"ge": -SENSOR_X_LIMIT_M, "le": SENSOR_X_LIMIT_M},
    }
    default: float = f.default  # type: ignore[assignment]
    lo, hi = f.metadata["bounds"]
    if kind != "position":  # the physical range (engine.vehicle), besides the sign
        ranges[kind] = ranges[kind] | {"le": hi} | ({"ge": lo} if lo > 0 else {})
        if lo > 0:
            ranges[kind].pop("gt", None)
    field = Field(default, allow_inf_nan=False, description=f"{what}, {unit}", **ranges[kind])
    return (float, field)


def _kind_field(kind: str, default: bool) -> Any:
    what = "Vehicle kind (engine.vehicle_kinds)"
    return (Literal[kind], Field(kind if default else ..., description=what))


# One model per idea: the schema is derived from the engine's dataclass (names, defaults,
# units, ranges), so a new vehicle parameter appears in the API without being re-typed here.
if TYPE_CHECKING:

    class VehicleParamsSchema(StrictModel):
        """Half-car parameters (fields: those of ``engine.vehicle.VehicleParams``)."""

    class BogieParamsSchema(StrictModel):
        """Bogie-vehicle parameters (fields: those of ``engine.bogie.BogieParams``)."""

else:
    VehicleParamsSchema = create_model(
        "VehicleParamsSchema",
        __base__=StrictModel,
        __doc__="Half-car parameters (SI); defaults are the paper's Table 1 vehicle.",
        kind=_kind_field(VehicleParams.kind, default=True),
        **{f.name: _schema_field(f) for f in dataclasses.fields(VehicleParams)},
    )
    BogieParamsSchema = create_model(
        "BogieParamsSchema",
        __base__=StrictModel,
        __doc__="Bogie-vehicle parameters as the datasheet gives them (whole vehicle, SI; "
        "secondary per bogie side, primary per axle box, contact per wheel); defaults are "
        "the passenger-coach preset.",
        kind=_kind_field(BogieParams.kind, default=False),
        **{f.name: _schema_field(f) for f in dataclasses.fields(BogieParams)},
    )


def _kind_of(data: Any) -> str:
    """The kind a parameter mapping (or model) is of; absent means the half car."""
    if isinstance(data, dict):
        kind = data.get("kind", VehicleParams.kind)
    else:
        kind = getattr(data, "kind", VehicleParams.kind)
    return kind if kind in _KIND_TAGS else VehicleParams.kind


_KIND_TAGS = (VehicleParams.kind, BogieParams.kind)

AnyVehicleParams = Annotated[
    Annotated[VehicleParamsSchema, Tag(VehicleParams.kind)]
    | Annotated[BogieParamsSchema, Tag(BogieParams.kind)],
    Discriminator(_kind_of),
]
"""The parameters of any vehicle kind, told apart by ``kind`` (default ``half_car``)."""

PARAM_NAMES = tuple(
    dict.fromkeys([*VehicleParamsSchema.model_fields, *BogieParamsSchema.model_fields])
)

BODY_MASS_BOUNDS: tuple[float, float] = next(
    f.metadata["bounds"] for f in dataclasses.fields(VehicleParams) if f.name == "ms"
)
"""Physical range of a body mass, kg (the engine's ``VehicleParams.ms``)."""


class VehicleCreate(StrictModel):
    """A new vehicle: a name and its parameters, nested in ``params`` or given at top level."""

    name: UrlName
    description: str | None = Field(default=None, max_length=2000)
    preset: str | None = Field(
        default=None,
        max_length=50,
        description="Start from this engine preset (any kind); parameters given override",
        json_schema_extra=closed_list(sorted(KIND_PRESETS)),
    )
    params: AnyVehicleParams = Field(default_factory=VehicleParamsSchema)

    @field_validator("params", mode="wrap")
    @classmethod
    def _untagged(cls, value: Any, handler: ValidatorFunctionWrapHandler) -> Any:
        # a bad parameter is named params.<name> whatever the kind (pydantic puts the
        # union's tag, e.g. params.bogie.<name>, in the location)
        try:
            return handler(value)
        except ValidationError as exc:
            errors: list[Any] = []
            for e in exc.errors():
                loc = tuple(e["loc"])
                if loc and loc[0] in _KIND_TAGS:
                    loc = loc[1:]
                detail = {"type": e["type"], "loc": loc, "input": e.get("input")}
                if "ctx" in e:
                    detail["ctx"] = e["ctx"]
                errors.append(detail)
            raise ValidationError.from_exception_data(exc.title, errors) from None

    @model_validator(mode="before")
    @classmethod
    def _lift_flat_params(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        flat = {k: data[k] for k in PARAM_NAMES if k in data}
        if not flat:
            return data
        nested = data.get("params") or {}
        if not isinstance(nested, dict):
            return data
        for k, v in flat.items():
            if k in nested and nested[k] != v:
                raise ValueError(f"parameter {k} is given twice with different values")
        rest = {k: v for k, v in data.items() if k not in PARAM_NAMES}
        return rest | {"params": {**nested, **flat}}


class VehiclePublic(BaseModel):
    """A stored vehicle."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    description: str | None
    params: dict[str, float | str] = Field(
        description="The parameters as stored (names and units of VehicleParamsSchema for "
        "a half car, of BogieParamsSchema with kind 'bogie' for a bogie vehicle; vehicles "
        "made before the physical ranges were enforced are shown as they are)"
    )
    version: int = Field(description="Current parameter version (1 at registration)")
    created_at: datetime


class VehiclesPublic(BaseModel):
    """A page of vehicles."""

    data: list[VehiclePublic]
    count: int


class VehicleEdit(StrictModel):
    """A manual edit: the parameters to change (SI); makes a new version, runs reprocessed."""

    params: dict[str, float] = Field(
        description='Parameters to change, e.g. {"ms": 17000}',
        json_schema_extra=closed_list(PARAM_NAMES),
    )
    note: str | None = Field(default=None, max_length=2000, description="Why (kept with it)")


class VehicleEditPreview(BaseModel):
    """What an edit would do (``PATCH ...?dry_run=true``); nothing was stored."""

    dry_run: Literal[True] = True
    vehicle: str
    version: int = Field(description="The version the edit would make")
    params: dict[str, float] = Field(description="The parameters after the edit, SI")
    changes: dict[str, tuple[float, float]] = Field(
        description="Each parameter that would change: [now, after]"
    )
    runs_reprocessed: int = Field(description="Runs that would be processed again")
    plausible: bool = Field(description="Whether the vehicle would be plausible as a whole")
    problems: list[str] = Field(description="Why it is not (empty when it is)")
    quantities: dict[str, float] = Field(
        description="Derived quantities judged: gyration_ratio, bounce_hz, pitch_hz, "
        "axle_hop_*_hz, deflection_*_mm (static suspension), wheel_load_*_kn (static)"
    )


class VehicleRestore(StrictModel):
    """Why an earlier version is restored (optional)."""

    note: str | None = Field(default=None, max_length=2000, description="Why (kept with it)")


class VehicleVersionPublic(BaseModel):
    """One parameter set a vehicle has had."""

    model_config = ConfigDict(from_attributes=True)

    version: int
    params: dict[str, float | str] = Field(description="The kind's parameters, SI")
    source: str = Field(description="created, manual, calibration or restore")
    calibration_id: int | None
    created_by: str | None = Field(description="API key name or 'automatic'")
    note: str | None
    created_at: datetime


class VehicleVersionsPublic(BaseModel):
    """A vehicle's parameter versions, newest first."""

    vehicle: str
    current: int
    data: list[VehicleVersionPublic]


class CalibrateRequest(StrictModel):
    """What to calibrate from and what to fit."""

    run_ids: list[int] | None = Field(
        default=None, max_length=10_000,
        description="Runs to use (default: every processed run of the vehicle)",
    )  # fmt: skip
    fit: list[str] | None = Field(
        default=None, min_length=1, max_length=8, json_schema_extra=closed_list(FITTABLE),
        description="Quantities to fit (default by the vehicle's kind: "
        + "; ".join(f"{k} {', '.join(v)}" for k, v in DEFAULT_FIT_BY_KIND.items())
        + ")",
    )  # fmt: skip
    apply: bool = Field(
        default=False,
        description="Make a significant result the vehicle's next version and reprocess its runs",
    )
    load_kg: float | None = Field(
        default=None, ge=BODY_MASS_BOUNDS[0], le=BODY_MASS_BOUNDS[1], allow_inf_nan=False,
        description=f"Known body mass (load/tare figure), kg, {BODY_MASS_BOUNDS[0]:g} to "
        f"{BODY_MASS_BOUNDS[1]:g} (the body mass's physical range): the only way to change m_s",
    )  # fmt: skip


class CalibrationAccepted(BaseModel):
    """A queued calibration."""

    id: int
    status: Literal["running", "done", "failed"]


class FittedParameterPublic(BaseModel):
    """One fitted quantity: registered and fitted values, relative change ± uncertainty."""

    name: str
    description: str
    unit: str
    before: dict[str, float]
    after: dict[str, float]
    change: float = Field(description="Relative change (fraction), or shift in m (sensor_x_m)")
    sd: float = Field(description="Standard uncertainty of the change (same unit)")
    identified: bool
    significant: bool
    at_bound: bool = Field(False, description="The fitted value sits at the fit's range")
    applied: bool | None = Field(
        None,
        description="In the calibrated vehicle (significant, not at the bound); false: the "
        "registered value is kept; null: calibrated before this was recorded",
    )


class CalibrationPublic(BaseModel):
    """A calibration and its outcome (objective: relative front/rear axle disagreement)."""

    id: int
    vehicle: str
    status: Literal["running", "done", "failed"]
    automatic: bool
    created_by: str | None
    created_at: datetime
    finished_at: datetime | None
    runs_used: list[int] = Field(description="Run ids calibrated from")
    fit: list[str] | None
    apply: bool = Field(description="Asked to apply a significant result")
    load_kg: float | None
    vehicle_version: int | None = Field(description="Version the calibration started from")
    params: dict[str, float] | None = Field(description="Calibrated vehicle (SI)")
    fitted: list[FittedParameterPublic]
    objective_before: float | None
    objective_after: float | None
    disagreement_before_mm: float | None
    disagreement_after_mm: float | None
    significant: bool | None
    message: str | None
    not_identified: dict[str, str]
    applied: bool
    applied_version: int | None
    details: dict[str, Any] | None = Field(
        description="Per-run objective, skipped runs, objective scans, evaluations, time"
    )
    error: dict[str, Any] | None


class CalibrationsPublic(BaseModel):
    """A vehicle's calibrations, newest first."""

    data: list[CalibrationPublic]
    count: int


class HealthAlertPublic(BaseModel):
    """A calibrated parameter that changed beyond its uncertainty."""

    vehicle: str
    parameter: str
    before: float
    after: float
    before_sd: float
    after_sd: float
    change: float = Field(description="Relative change, fraction")
    sigmas: float = Field(description="Change in combined standard uncertainties")
    since: datetime = Field(description="When the runs showing the new value start")
    reference: str
    source: str
    message: str


class HealthPointPublic(BaseModel):
    """One calibrated value of a parameter (the history behind the alerts)."""

    parameter: str
    value: float
    sd: float
    at: datetime
    source: str


class VehicleHealthPublic(BaseModel):
    """Suspension health of a vehicle."""

    vehicle: str
    alerts: list[HealthAlertPublic]
    history: list[HealthPointPublic]
