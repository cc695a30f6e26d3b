"""Whether a vehicle is physically plausible as a whole, and whether a result is.

Each parameter of :class:`~engine.vehicle.VehicleParams` has its own physical range, but values
that are each in range can together describe no vehicle: a 0.5 t body with the pitch inertia
of a 100 t one (a radius of gyration of 447 m) inverts into profiles 60-229 mm deep. This
module derives the quantities an engineer judges a vehicle by (radius of gyration against the
axle spacing, body and axle natural frequencies, static suspension deflection, static wheel
load) and checks each against a stated range.

Checks are functions of *derived quantities*, not of one kind's parameters: a vehicle kind
registers in :data:`KINDS` how it derives its quantities (by the names of :data:`RANGES`) and
which of them it has; the ranges and the messages are shared.

A processed run is checked the same way (:func:`check_result`): its level may not deviate
from its baseline, nor a dip be deeper, than rail geometry plus what the track can deflect
under the vehicle (:func:`result_bound_mm`). Beyond it the result is the vehicle model's, not
the track's.

Units: SI inside; frequencies in Hz, deflections and depths in mm in the quantities.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .bogie import BogieParams
from .errors import InversionError, ParameterError
from .plausibility import WHEEL_LOAD_MAX_N, WHEEL_LOAD_MIN_N
from .track import TrackParams
from .vehicle import GRAVITY, VehicleModel, VehicleParams


@dataclass(frozen=True)
class PlausibleRange:
    """The range a derived quantity of any rail vehicle lies in.

    Attributes
    ----------
    what : str
        What the quantity is, for messages.
    unit : str
        Its unit.
    lo, hi : float
        Inclusive bounds.
    why : str
        Where the bounds come from (shown in the message).
    """

    what: str
    unit: str
    lo: float
    hi: float
    why: str

    def contains(self, value: float) -> bool:
        """Whether ``value`` is a finite number within the bounds."""
        return math.isfinite(value) and self.lo <= value <= self.hi


RANGES: dict[str, PlausibleRange] = {
    "gyration_ratio": PlausibleRange(
        "body radius of gyration over half the axle spacing",
        "",
        0.3,
        2.0,
        "a uniform body of length L has a radius of gyration L/sqrt(12); rail car bodies are "
        "1 to 2.5 times their axle (or bogie) spacing long, a ratio of 0.58 to 1.44, widened "
        "for mass concentrated at the centre or at the ends",
    ),
    "bounce_hz": PlausibleRange(
        "body bounce natural frequency",
        "Hz",
        0.3,
        10.0,
        "passenger cars ride at 0.6-1.5 Hz, loaded freight wagons at 2-5 Hz, empty stiff "
        "wagons up to about 8 Hz",
    ),
    "pitch_hz": PlausibleRange(
        "body pitch natural frequency",
        "Hz",
        0.3,
        15.0,
        "body pitch lies near the bounce frequency (0.8-3 Hz for passenger cars, a few Hz for "
        "wagons); below 0.3 Hz the body is far heavier in pitch than in bounce",
    ),
    "axle_hop_front_hz": PlausibleRange(
        "front axle-hop natural frequency",
        "Hz",
        2.0,
        500.0,
        "an unsprung mass on its suspension and contact springs resonates well above the body "
        "(the model's contact spring gives ~9 Hz for Table 1; wheelset on track 20-100 Hz)",
    ),
    "axle_hop_rear_hz": PlausibleRange(
        "rear axle-hop natural frequency",
        "Hz",
        2.0,
        500.0,
        "as the front axle",
    ),
    "deflection_front_mm": PlausibleRange(
        "static deflection of the front suspension under the body",
        "mm",
        1.0,
        500.0,
        "steel-sprung freight suspensions deflect 10-100 mm, passenger (air) suspensions "
        "150-300 mm; no suspension has half a metre of stroke",
    ),
    "deflection_rear_mm": PlausibleRange(
        "static deflection of the rear suspension under the body",
        "mm",
        1.0,
        500.0,
        "as the front suspension",
    ),
    "wheel_load_front_kn": PlausibleRange(
        "static front wheel load",
        "kN",
        WHEEL_LOAD_MIN_N / 1e3,
        WHEEL_LOAD_MAX_N / 1e3,
        "the wheel loads a log's load-weigh column may show (engine.plausibility)",
    ),
    "wheel_load_rear_kn": PlausibleRange(
        "static rear wheel load",
        "kN",
        WHEEL_LOAD_MIN_N / 1e3,
        WHEEL_LOAD_MAX_N / 1e3,
        "as the front wheel",
    ),
}
"""Plausible range of each derived quantity, by name (shared by every vehicle kind)."""


def _series(a: float, b: float) -> float:
    return a * b / (a + b)


def half_car_quantities(vp: VehicleParams) -> dict[str, float]:
    """The derived quantities of a half-car (names of :data:`RANGES`).

    The body modes use the suspension and contact springs in series (the axles move with
    the body at body frequencies); the axle modes the two springs in parallel (the body
    stands still at axle frequencies). Bounce and pitch are taken uncoupled.
    """
    k1, k2 = _series(vp.ks1, vp.kt1), _series(vp.ks2, vp.kt2)
    half = 0.5 * vp.wheelbase
    body1 = vp.ms * GRAVITY * vp.d2 / vp.wheelbase
    body2 = vp.ms * GRAVITY * vp.d1 / vp.wheelbase
    front, rear = vp.static_axle_loads()
    two_pi = 2.0 * math.pi
    return {
        "gyration_ratio": math.sqrt(vp.Is / vp.ms) / half,
        "bounce_hz": math.sqrt((k1 + k2) / vp.ms) / two_pi,
        "pitch_hz": math.sqrt((k1 * vp.d1**2 + k2 * vp.d2**2) / vp.Is) / two_pi,
        "axle_hop_front_hz": math.sqrt((vp.ks1 + vp.kt1) / vp.mu1) / two_pi,
        "axle_hop_rear_hz": math.sqrt((vp.ks2 + vp.kt2) / vp.mu2) / two_pi,
        "deflection_front_mm": 1e3 * body1 / vp.ks1,
        "deflection_rear_mm": 1e3 * body2 / vp.ks2,
        "wheel_load_front_kn": front / 1e3,
        "wheel_load_rear_kn": rear / 1e3,
    }


def bogie_quantities(bp: BogieParams) -> dict[str, float]:
    """The derived quantities of a bogie vehicle: those of its lumped half car (each bogie
    one "axle" on its suspensions in series, :meth:`BogieParams.lumped_half_car`), with the
    static wheel load per wheel (the lumped "axle" carries a bogie's two wheels)."""
    q = half_car_quantities(bp.lumped_half_car())
    wheels = bp.static_wheel_loads()
    q["wheel_load_front_kn"] = float(wheels[0]) / 1e3
    q["wheel_load_rear_kn"] = float(wheels[-1]) / 1e3
    return q


@dataclass(frozen=True)
class VehicleKind:
    """How one kind of vehicle model is judged: its derived quantities (names of
    :data:`RANGES`), and the parameters each depends on (named in messages)."""

    quantities: Callable[[Any], Mapping[str, float]]
    depends_on: Mapping[str, tuple[str, ...]]


KINDS: dict[str, VehicleKind] = {
    "half_car": VehicleKind(
        half_car_quantities,
        {
            "gyration_ratio": ("Is", "ms", "d1", "d2"),
            "bounce_hz": ("ms", "ks1", "ks2", "kt1", "kt2"),
            "pitch_hz": ("Is", "ks1", "ks2", "kt1", "kt2", "d1", "d2"),
            "axle_hop_front_hz": ("mu1", "ks1", "kt1"),
            "axle_hop_rear_hz": ("mu2", "ks2", "kt2"),
            "deflection_front_mm": ("ms", "ks1", "d1", "d2"),
            "deflection_rear_mm": ("ms", "ks2", "d1", "d2"),
            "wheel_load_front_kn": ("ms", "mu1", "d1", "d2"),
            "wheel_load_rear_kn": ("ms", "mu2", "d1", "d2"),
        },
    ),
    "bogie": VehicleKind(
        bogie_quantities,
        {
            "gyration_ratio": ("body_pitch_inertia_kgm2", "body_mass_kg", "bogie_half_spacing_m"),
            "bounce_hz": ("body_mass_kg", "secondary_k_n_per_m", "primary_k_n_per_m"),
            "pitch_hz": (
                "body_pitch_inertia_kgm2",
                "secondary_k_n_per_m",
                "primary_k_n_per_m",
                "bogie_half_spacing_m",
            ),
            "axle_hop_front_hz": (
                "bogie_mass_kg",
                "wheelset_mass_kg",
                "primary_k_n_per_m",
                "contact_k_n_per_m",
            ),
            "axle_hop_rear_hz": (
                "bogie_mass_kg",
                "wheelset_mass_kg",
                "primary_k_n_per_m",
                "contact_k_n_per_m",
            ),
            "deflection_front_mm": ("body_mass_kg", "secondary_k_n_per_m", "primary_k_n_per_m"),
            "deflection_rear_mm": ("body_mass_kg", "secondary_k_n_per_m", "primary_k_n_per_m"),
            "wheel_load_front_kn": ("body_mass_kg", "bogie_mass_kg", "wheelset_mass_kg"),
            "wheel_load_rear_kn": ("body_mass_kg", "bogie_mass_kg", "wheelset_mass_kg"),
        },
    ),
}
"""Vehicle kinds by name; a new kind registers its derived quantities here."""


@dataclass(frozen=True)
class Implausibility:
    """A derived quantity outside its range."""

    quantity: str
    value: float
    range: PlausibleRange
    depends_on: tuple[str, ...]

    @property
    def message(self) -> str:
        """Plain words: the quantity, its value, the range and why."""
        r = self.range
        unit = f" {r.unit}" if r.unit else ""
        return (
            f"{r.what} ({self.quantity}) is {self.value:.3g}{unit}, outside the plausible "
            f"{r.lo:g} to {r.hi:g}{unit} of a rail vehicle ({r.why}); it follows from "
            f"{', '.join(self.depends_on)}"
        )


class VehicleImplausible(ParameterError):
    """Parameters each in range that together describe no rail vehicle.

    Attributes
    ----------
    quantity : str
        The first derived quantity out of range (name in :data:`RANGES`).
    findings : list of Implausibility
        Every quantity out of range.
    """

    def __init__(self, findings: list[Implausibility], field: str | None = None) -> None:
        text = "; ".join(f.message for f in findings)
        super().__init__(f"the vehicle is not physically plausible: {text}", field=field)
        self.findings = findings
        self.quantity = findings[0].quantity


def vehicle_quantities(vp: Any, kind: str = "half_car") -> dict[str, float]:
    """The derived quantities of a vehicle of ``kind`` (see :data:`KINDS`)."""
    try:
        k = KINDS[kind]
    except KeyError:
        raise ParameterError(
            f"unknown vehicle kind {kind!r}; expected one of {sorted(KINDS)}", field="kind"
        ) from None
    return dict(k.quantities(vp))


def implausibilities(vp: Any, kind: str = "half_car") -> list[Implausibility]:
    """Every derived quantity of the vehicle outside its range (empty: plausible)."""
    k = KINDS[kind]
    out = []
    for name, value in vehicle_quantities(vp, kind).items():
        r = RANGES[name]
        if not r.contains(value):
            out.append(Implausibility(name, value, r, tuple(k.depends_on.get(name, ()))))
    return out


def check_vehicle(vp: Any, kind: str = "half_car", *, field: str | None = "params") -> None:
    """Refuse a vehicle that is not physically plausible as a whole.

    Raises
    ------
    VehicleImplausible
        Naming every derived quantity out of range, its range, why, and the parameters it
        follows from (``field``: the request field named).
    """
    found = implausibilities(vp, kind)
    if found:
        raise VehicleImplausible(found, field=field)


GEOMETRY_LIMIT_MM = 28.0
"""Largest isolated longitudinal-level defect a track in service is left with, mm: the
EN 13848-5 immediate-action limit for D1 at up to 80 km/h, mean to peak, **as recalled, not
verified** (the standard's tables were not found in any source open to the product). The bound
built on it carries a factor 2 (``RESULT_MARGIN``), so a limit a few mm off moves it little."""

SUPPORT_LOSS_LIMIT = 0.9
"""Largest support-stiffness loss allowed for in the deflection bound (fraction)."""

DYNAMIC_FACTOR = 2.0
"""Dynamic wheel load over the static one allowed for in the deflection bound."""

RESULT_MARGIN = 2.0
"""Factor between the bound a result is refused at and geometry plus deflection."""


def result_bound_mm(vehicle: VehicleModel, track: TrackParams) -> float:
    """Largest plausible deviation of a processed level from its baseline (or dip depth), mm.

    ``RESULT_MARGIN * (GEOMETRY_LIMIT_MM + w)``, with ``w`` the static deflection of the
    track (continuous Winkler beam) under ``DYNAMIC_FACTOR`` times the heavier static wheel
    load, on supports that lost ``SUPPORT_LOSS_LIMIT`` of their stiffness: no rail geometry
    left in service plus no support failure short of a missing sleeper deflects further.
    About 67 mm for the Table 1 vehicle on the default track (w = 5.5 mm).
    """
    load = DYNAMIC_FACTOR * float(max(vehicle.static_wheel_loads()))
    w_mm = 1e3 * track.winkler_deflection(load, 1.0 - SUPPORT_LOSS_LIMIT)
    return RESULT_MARGIN * (GEOMETRY_LIMIT_MM + w_mm)


class ImplausibleResult(InversionError):
    """A processed run whose levels no track can show: the vehicle model is wrong for it."""


def check_result(
    level_mm: Any,
    baseline_mm: Any,
    depths_mm: Any,
    vehicle: VehicleModel,
    track: TrackParams,
) -> None:
    """Refuse a processed run whose level or dips lie beyond :func:`result_bound_mm`.

    Parameters
    ----------
    level_mm, baseline_mm : array_like
        The fused loaded level and its baseline on the run's grid, mm (NaN: not covered).
    depths_mm : array_like
        Depths of the dips found, mm.

    Raises
    ------
    ImplausibleResult
        Naming the largest deviation or depth, where the bound comes from, and what to check.
    """
    bound = result_bound_mm(vehicle, track)
    dev = np.abs(np.asarray(level_mm, dtype=np.float64) - np.asarray(baseline_mm))
    dev = dev[np.isfinite(dev)]
    worst_dev = float(dev.max()) if dev.size else 0.0
    depths = np.asarray(depths_mm, dtype=np.float64)
    worst_dip = float(np.nanmax(depths)) if depths.size else 0.0
    worst, what = max((worst_dev, "the level deviates from its baseline by"),
                      (worst_dip, "a dip is"))  # fmt: skip
    if worst > bound or not math.isfinite(worst):
        raise ImplausibleResult(
            f"the processed result is not physically plausible: {what} {worst:.1f} mm, more "
            f"than the {bound:.0f} mm any track can show under this vehicle ({RESULT_MARGIN:g} "
            f"x ({GEOMETRY_LIMIT_MM:g} mm of rail geometry at the immediate-action limit + "
            f"the track's deflection under {DYNAMIC_FACTOR:g} x the static wheel load on "
            f"supports {SUPPORT_LOSS_LIMIT:.0%} softened)); the vehicle's parameters are "
            "likely wrong for this run (restore an earlier vehicle version)"
        )
