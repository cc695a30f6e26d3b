"""The vehicle kinds, looked up by name in :data:`VEHICLE_KINDS`.

Every kind is a frozen dataclass of its datasheet values that gives what
:class:`engine.vehicle.VehicleModel` lists: its wheels' positions relative to the body centre,
its equations (mass, damping and stiffness matrices), its static wheel loads and the two
points the inversion measures. The half car is the kind with one wheel per measured point.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from .bogie import FREIGHT_WAGON, PASSENGER_COACH, BogieParams
from .errors import ParameterError
from .vehicle import HEAVY, TABLE1, VehicleParams

Vehicle = VehicleParams | BogieParams
"""Any registered vehicle kind."""

VEHICLE_KINDS: dict[str, type[VehicleParams] | type[BogieParams]] = {
    VehicleParams.kind: VehicleParams,
    BogieParams.kind: BogieParams,
}
"""The vehicle kinds by name (``params["kind"]``; absent means the half car)."""

KIND_PRESETS: dict[str, Vehicle] = {
    "table1": TABLE1,
    "heavy": HEAVY,
    "passenger_coach": PASSENGER_COACH,
    "freight_wagon": FREIGHT_WAGON,
}
"""Every vehicle preset by name, of any kind."""


def vehicle_from_dict(data: dict[str, Any]) -> Vehicle:
    """The vehicle of a parameter mapping; its ``kind`` (default ``half_car``) picks the class.

    Raises
    ------
    ParameterError
        ``field="kind"`` for an unknown kind; otherwise as the kind's ``from_dict``.
    """
    kind = data.get("kind", VehicleParams.kind)
    cls = VEHICLE_KINDS.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise ParameterError(
            f"unknown vehicle kind {kind!r}; expected one of {sorted(VEHICLE_KINDS)}",
            field="kind",
        )
    return cls.from_dict(data)


Force = TypeVar("Force", float, NDArray[np.float64])


def per_wheel(point_force_n: Force, wheel_offsets_m: Sequence[float]) -> Force:
    """The load per wheel of a measured point's force, N.

    A measured point's force is that of all its wheels together (a half car's axle: one
    wheel; a bogie centre: its two); wheel loads compare across vehicle kinds only per wheel.

    Parameters
    ----------
    point_force_n : float or ndarray
        Contact force of the measured point, N (compression positive).
    wheel_offsets_m : sequence of float
        The point's wheels about it, m (``vehicle.axle_wheel_offsets_m[0]``): their count
        shares the force.
    """
    n = len(wheel_offsets_m)
    if n < 1:
        raise ParameterError("a measured point has at least one wheel", field="wheel_offsets_m")
    return point_force_n / n
