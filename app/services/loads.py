"""A run's declared load: what the log cannot know about the wheel force.

The inversion's wheel force comes from the vehicle's equations (static + dynamic), so the
static part is that of the registered vehicle. A client that knows better declares either the
``payload_kg`` carried (on top of the registered body mass) or the measured
``static_wheel_load_n`` (mean static wheel load of the half-car's two axles, N); either gives
the body mass the run is inverted with. The payload is assumed spread like the body's own mass
(pitch inertia scaled with the body mass, axle loads shared as before). A log with a
load-weigh column (:attr:`engine.runlog.RunLog.wheel_load_n`) declares its static wheel load
itself; a value given with the upload wins over it.

Units: kg, N.
"""

from __future__ import annotations

from engine.runlog import RunLog
from engine.vehicle import GRAVITY, VehicleParams

from .errors import Invalid

LOGGED_LOAD_FIELD = "wheel_load_column"
"""Field named when the static wheel load read from a log's load-weigh column is refused."""


def declared_wheel_load(
    log: RunLog, payload_kg: float | None, static_wheel_load_n: float | None
) -> tuple[float | None, str]:
    """The static wheel load a run declares, N, and the field it came from.

    The upload's ``static_wheel_load_n`` wins; a ``payload_kg`` says the load instead (None is
    returned); else the median of the log's load-weigh column; else None (the registered
    vehicle's load).
    """
    if static_wheel_load_n is not None or payload_kg is not None:
        return static_wheel_load_n, "static_wheel_load_n"
    return log.static_wheel_load_n(), LOGGED_LOAD_FIELD


def declared_body_mass(
    vehicle: VehicleParams, payload_kg: float | None, static_wheel_load_n: float | None
) -> float | None:
    """The body mass a declared load gives, kg (None: nothing declared; not checked).

    A payload is carried on top of the registered body mass; two axles carry the body and
    themselves: ``2 W = (ms + mu1 + mu2) g``.
    """
    if payload_kg is not None:
        return vehicle.ms + payload_kg
    if static_wheel_load_n is not None:
        return 2.0 * static_wheel_load_n / GRAVITY - vehicle.mu1 - vehicle.mu2
    return None


def loaded_vehicle(
    vehicle: VehicleParams,
    payload_kg: float | None = None,
    static_wheel_load_n: float | None = None,
    *,
    field: str = "static_wheel_load_n",
) -> VehicleParams:
    """The vehicle as it ran: registered parameters with the declared load applied.

    ``field`` is the field named when the wheel load is refused (where it came from).

    Raises
    ------
    Invalid
        Naming the field when both are given, or when the wheel load is below what the
        vehicle's axles alone weigh.
    """
    if payload_kg is not None and static_wheel_load_n is not None:
        raise Invalid(
            "give either payload_kg or static_wheel_load_n, not both", field="static_wheel_load_n"
        )
    ms = declared_body_mass(vehicle, payload_kg, static_wheel_load_n)
    if ms is None:
        return vehicle
    if static_wheel_load_n is not None and ms <= 0.1 * vehicle.ms:
        axles = 0.5 * (vehicle.mu1 + vehicle.mu2) * GRAVITY
        raise Invalid(
            f"static_wheel_load_n {static_wheel_load_n:g} N is not plausible for this "
            f"vehicle: its axles alone weigh {axles:.0f} N per wheel and the body "
            f"{0.5 * vehicle.ms * GRAVITY:.0f} N (give the mean static wheel load, N)",
            field=field,
        )
    return vehicle.with_body_mass(ms)
