"""Vehicle schemas: the half-car parameter set (SI units, the engine's ``VehicleParams``)."""

from __future__ import annotations

from datetime import datetime
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator

from .common import StrictModel, UrlName


def _p(default: float, unit: str, what: str, *, ge0: bool = False) -> Any:
    if ge0:
        return Field(default=default, ge=0, allow_inf_nan=False, description=f"{what}, {unit}")
    return Field(default=default, gt=0, allow_inf_nan=False, description=f"{what}, {unit}")


class VehicleParamsSchema(StrictModel):
    """Half-car parameters; defaults are the paper's Table 1 vehicle."""

    ms: float = _p(16200.0, "kg", "Body mass")
    Is: float = _p(111193.0, "kg m²", "Body pitch inertia")
    mu1: float = _p(700.0, "kg", "Front axle mass")
    mu2: float = _p(1100.0, "kg", "Rear axle mass")
    ks1: float = _p(0.4e6, "N/m", "Front suspension stiffness")
    ks2: float = _p(1.0e6, "N/m", "Rear suspension stiffness")
    cs1: float = _p(10e3, "N s/m", "Front suspension damping", ge0=True)
    cs2: float = _p(20e3, "N s/m", "Rear suspension damping", ge0=True)
    kt1: float = _p(1.75e6, "N/m", "Front contact stiffness")
    kt2: float = _p(3.5e6, "N/m", "Rear contact stiffness")
    d1: float = _p(4.13, "m", "Distance body centre to front axle")
    d2: float = _p(4.13, "m", "Distance body centre to rear axle")


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
