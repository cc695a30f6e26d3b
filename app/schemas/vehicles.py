"""Vehicle schemas: the half-car parameter set (SI units, the engine's ``VehicleParams``)."""

from __future__ import annotations

import dataclasses
from datetime import datetime
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, ConfigDict, Field, create_model, model_validator

from engine.vehicle import SENSOR_X_LIMIT_M, VehicleParams

from .common import StrictModel, UrlName


def _schema_field(f: dataclasses.Field[Any]) -> Any:
    """The pydantic field of one ``VehicleParams`` field: same default, unit and range."""
    unit, kind, what = f.metadata["unit"], f.metadata["kind"], f.metadata["description"]
    ranges: dict[str, dict[str, Any]] = {
        "positive": {"gt": 0.0},
        "nonnegative": {"ge": 0.0},
        "position": {"ge": -SENSOR_X_LIMIT_M, "le": SENSOR_X_LIMIT_M},
    }
    default: float = f.default  # type: ignore[assignment]
    field = Field(default, allow_inf_nan=False, description=f"{what}, {unit}", **ranges[kind])
    return (float, field)


# One model per idea: the schema is derived from the engine's dataclass (names, defaults,
# units, ranges), so a new vehicle parameter appears in the API without being re-typed here.
if TYPE_CHECKING:

    class VehicleParamsSchema(StrictModel):
        """Half-car parameters (fields: those of ``engine.vehicle.VehicleParams``)."""

else:
    VehicleParamsSchema = create_model(
        "VehicleParamsSchema",
        __base__=StrictModel,
        __doc__="Half-car parameters (SI); defaults are the paper's Table 1 vehicle.",
        **{f.name: _schema_field(f) for f in dataclasses.fields(VehicleParams)},
    )


PARAM_NAMES = tuple(VehicleParamsSchema.model_fields)


class VehicleCreate(StrictModel):
    """A new vehicle: a name and its parameters, nested in ``params`` or given at top level."""

    name: UrlName
    description: str | None = Field(default=None, max_length=2000)
    params: VehicleParamsSchema = Field(default_factory=VehicleParamsSchema)

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
    params: VehicleParamsSchema
    created_at: datetime


class VehiclesPublic(BaseModel):
    """A page of vehicles."""

    data: list[VehiclePublic]
    count: int
