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

from app.services.errors import Invalid
from engine.runlog import RunLog
from engine.vehicle import GRAVITY
from engine.vehicle_kinds import Vehicle as EngineVehicle

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
    vehicle: EngineVehicle, payload_kg: float | None, static_wheel_load_n: float | None
) -> float | None:
    """The (per-rail) body mass a declared load gives, kg (None: nothing declared; not
    checked).

    A payload (on the whole vehicle, shared by the rails its parameters describe,
    ``vehicle.rails``) is carried on top of the registered body mass; the ``n`` wheels of a
    rail carry
    the body and the rest of the vehicle's mass ``m_rest``: ``n W = (ms + m_rest) g`` (the
    half car: ``2 W = (ms + mu1 + mu2) g``).
    """
    if payload_kg is not None:
        return vehicle.ms + payload_kg / vehicle.rails
    if static_wheel_load_n is not None:
        n = vehicle.contact_k.size
        return n * static_wheel_load_n / GRAVITY - _rest_mass(vehicle)
    return None


def _rest_mass(vehicle: EngineVehicle) -> float:
    """Per-rail mass of everything but the body, kg."""
    return float(-vehicle.gravity_load().sum() / GRAVITY - vehicle.ms)


def loaded_vehicle(
    vehicle: EngineVehicle,
    payload_kg: float | None = None,
    static_wheel_load_n: float | None = None,
    *,
    field: str = "static_wheel_load_n",
) -> EngineVehicle:
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
        axles = _rest_mass(vehicle) * GRAVITY / vehicle.contact_k.size
        raise Invalid(
            f"static_wheel_load_n {static_wheel_load_n:g} N is not plausible for this "
            f"vehicle: its axles alone weigh {axles:.0f} N per wheel and the body "
            f"{vehicle.ms * GRAVITY / vehicle.contact_k.size:.0f} N (give the mean static "
            "wheel load, N)",
            field=field,
        )
    return vehicle.with_body_mass(ms)
