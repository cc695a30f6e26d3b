"""The 4-DOF half-car vehicle (body bounce and pitch, two axles).

Degrees of freedom ``[u_s, theta_s, u_u1, u_u2]``: body bounce (m, positive up), body pitch
(rad, positive nose-up), front-axle and rear-axle displacement (m, positive up). Axle 1 leads,
``d1`` ahead of the body centre of gravity; axle 2 trails ``d2`` behind it.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any, ClassVar, Protocol, Self

import numpy as np
from numpy.typing import NDArray

from .errors import ParameterError, as_number, check_range, reject_unknown_keys

GRAVITY = 9.81
"""Acceleration of gravity used by the model, m/s²."""


SENSOR_X_LIMIT_M = 15.0
"""Largest accepted distance of the accelerometer from the body CG, m (half a 30 m car body)."""


def _param(
    default: float, unit: str, what: str, kind: str = "positive",
    bounds: tuple[float, float] = (0.0, math.inf),
) -> Any:  # fmt: skip
    """A parameter field: default, unit, description and accepted range.

    ``kind`` is ``"positive"`` (> 0), ``"nonnegative"`` (>= 0) or ``"position"`` (a signed
    distance, ``|x| <= SENSOR_X_LIMIT_M``); ``bounds`` is the physical range (inclusive) any
    rail vehicle's value lies in: outside it the model is not a vehicle (1e308 masses gave
    runs without a profile).
    """
    meta = {"unit": unit, "description": what, "kind": kind, "bounds": bounds}
    return field(default=default, metadata=meta)


def check_fields(params: Any) -> None:
    """Check and coerce every field of a vehicle dataclass made with :func:`_param`.

    Each value becomes a float; :class:`ParameterError` (``field=<name>``) when it is not a
    finite number of its kind or lies outside its physical bounds.
    """
    for f in fields(params):
        unit, kind = f.metadata["unit"], f.metadata["kind"]
        value = as_number(getattr(params, f.name), f.name, f"vehicle parameter {f.name}", unit)
        object.__setattr__(params, f.name, value)
        if not math.isfinite(value):
            raise ParameterError(
                f"vehicle parameter {f.name} must be finite, got {value}", field=f.name
            )
        if kind == "position":
            if abs(value) > SENSOR_X_LIMIT_M:
                raise ParameterError(
                    f"vehicle parameter {f.name} must lie within ±{SENSOR_X_LIMIT_M:g} {unit} "
                    f"of the body centre, got {value}",
                    field=f.name,
                )
        elif kind == "nonnegative":
            if value < 0:
                raise ParameterError(
                    f"vehicle parameter {f.name} ({f.metadata['description'].lower()}, "
                    f"{unit}) must be >= 0, got {value}",
                    field=f.name,
                )
        elif value <= 0:
            raise ParameterError(
                f"vehicle parameter {f.name} must be > 0 {unit}, got {value}", field=f.name
            )
        if kind != "position":
            lo, hi = f.metadata["bounds"]
            what = f"vehicle parameter {f.name} ({f.metadata['description'].lower()})"
            check_range(value, f.name, what, lo, hi, unit)


Link = tuple[NDArray[np.float64], float, float]
"""A suspension element: the DOF combination it stretches (its extension per unit DOF
displacement), its stiffness (N/m) and its damping (N s/m)."""


class VehicleKindBase:
    """What every vehicle kind's parameter dataclass shares: checked fields, building from a
    mapping, validated copies, and its equations assembled from its masses and suspension.

    A kind sets :attr:`kind` and :attr:`what` and gives :meth:`masses`,
    :meth:`suspension_links`, ``contact_dofs`` and ``contact_k``.
    """

    kind: ClassVar[str]
    what: ClassVar[str]
    """How a parameter of the kind is named in messages (``"vehicle parameter"``)."""
    __dataclass_fields__: ClassVar[dict[str, Any]]  # every kind is a dataclass

    def __post_init__(self) -> None:
        check_fields(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Self:
        """Build from a mapping (``kind`` may be given: it must be the class's); unknown keys
        are an error, missing ones take the kind's defaults."""
        data = dict(data)
        kind = data.pop("kind", cls.kind)
        if kind != cls.kind:
            raise ParameterError(f"vehicle kind must be {cls.kind!r}, got {kind!r}", field="kind")
        reject_unknown_keys(data, (f.name for f in fields(cls)), cls.what)
        return cls(**data)

    def to_dict(self) -> dict[str, Any]:
        """Parameters as a plain dict (SI units)."""
        return asdict(self)

    def replace(self, **changes: float) -> Self:
        """A copy with some parameters changed (validated like a new one)."""
        return self.from_dict({**self.to_dict(), **changes})

    def masses(self) -> NDArray[np.float64]:
        """Mass (kg) or inertia (kg m²) of each DOF."""
        raise NotImplementedError

    def suspension_links(self) -> list[Link]:
        """The suspension elements between the DOFs (contact springs apart)."""
        raise NotImplementedError

    @property
    def contact_dofs(self) -> NDArray[np.intp]:
        """DOF index of each wheel."""
        raise NotImplementedError

    @property
    def contact_k(self) -> NDArray[np.float64]:
        """Contact stiffness of each wheel, N/m."""
        raise NotImplementedError

    def matrices(
        self,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Mass, damping and stiffness matrices of the free vehicle (contact springs included),
        SI, shape ``(n_dof, n_dof)``.

        ``M`` is diagonal (:meth:`masses`); each suspension link ``(v, k, c)`` adds ``k v vᵀ``
        to ``K`` and ``c v vᵀ`` to ``C``; ``K`` has each wheel's contact stiffness on its
        DOF's diagonal, and the rail level enters that wheel's equation as ``k_c y``.
        """
        M = np.diag(self.masses())
        n = M.shape[0]
        links = self.suspension_links()
        K = sum((k * np.outer(v, v) for v, k, _ in links), np.zeros((n, n)))
        C = sum((c * np.outer(v, v) for v, _, c in links), np.zeros((n, n)))
        K[self.contact_dofs, self.contact_dofs] += self.contact_k
        return M, C, K


@dataclass(frozen=True)
class VehicleParams(VehicleKindBase):
    """Parameters of the half-car; defaults are the paper's Table 1 vehicle.

    Parameters
    ----------
    ms : float
        Body mass, kg.
    Is : float
        Body pitch inertia about the centre of gravity, kg m².
    mu1, mu2 : float
        Front and rear axle (unsprung) masses, kg.
    ks1, ks2 : float
        Front and rear suspension stiffness, N/m.
    cs1, cs2 : float
        Front and rear suspension damping, N s/m (may be zero).
    kt1, kt2 : float
        Front and rear contact ("tyre") stiffness, N/m.
    d1, d2 : float
        Distance from the body centre of gravity to the front and rear axle, m.
    sensor_x_m : float
        Longitudinal position of the accelerometer from the body centre of gravity, m,
        positive towards the front axle (default 0: at the CG). The accelerometer then
        measures ``ü_s + sensor_x_m · θ̈_s``; the chainage reference stays the body CG.

    Raises
    ------
    ParameterError
        If a mass, inertia, stiffness or distance is not a finite positive number, a damping
        is negative or not finite, or the sensor lies more than ``SENSOR_X_LIMIT_M`` from the
        CG.
    """

    ms: float = _param(16200.0, "kg", "Body mass", bounds=(500.0, 5e5))
    Is: float = _param(111193.0, "kg m²", "Body pitch inertia", bounds=(100.0, 1e8))
    mu1: float = _param(700.0, "kg", "Front axle mass", bounds=(10.0, 2e4))
    mu2: float = _param(1100.0, "kg", "Rear axle mass", bounds=(10.0, 2e4))
    ks1: float = _param(0.4e6, "N/m", "Front suspension stiffness", bounds=(1e3, 1e9))
    ks2: float = _param(1.0e6, "N/m", "Rear suspension stiffness", bounds=(1e3, 1e9))
    cs1: float = _param(10e3, "N s/m", "Front suspension damping", "nonnegative", (0.0, 1e8))
    cs2: float = _param(20e3, "N s/m", "Rear suspension damping", "nonnegative", (0.0, 1e8))
    kt1: float = _param(1.75e6, "N/m", "Front contact stiffness", bounds=(1e4, 1e11))
    kt2: float = _param(3.5e6, "N/m", "Rear contact stiffness", bounds=(1e4, 1e11))
    d1: float = _param(4.13, "m", "Distance body centre to front axle", bounds=(0.3, 30.0))
    d2: float = _param(4.13, "m", "Distance body centre to rear axle", bounds=(0.3, 30.0))
    sensor_x_m: float = _param(
        0.0, "m", "Accelerometer position from the body centre, towards the front axle",
        "position",
    )  # fmt: skip

    kind: ClassVar[str] = "half_car"
    rails: ClassVar[int] = 1
    """Rails the parameters describe: the half car's are one rail's already."""

    what: ClassVar[str] = "vehicle parameter"

    def with_body_mass(self, ms: float) -> VehicleParams:
        """The vehicle with another body mass, kg (a payload carried, a load figure).

        The difference is taken as spread like the body's own mass: the pitch inertia (kg m²)
        scales with the body mass, axle masses and the axle loads' split stay. This is how a
        run's declared load enters its inversion and its calibration.
        """
        return self.replace(ms=ms, Is=self.Is * ms / self.ms)

    @property
    def wheelbase(self) -> float:
        """Distance between the two axles, m."""
        return self.d1 + self.d2

    def static_axle_loads(self, g: float = GRAVITY) -> tuple[float, float]:
        """Static wheel-rail contact forces of the front and rear axle, N (compression > 0)."""
        body1 = self.ms * g * self.d2 / (self.d1 + self.d2)
        body2 = self.ms * g * self.d1 / (self.d1 + self.d2)
        return body1 + self.mu1 * g, body2 + self.mu2 * g

    # -- the vehicle-kind interface (engine.vehicle_kinds): the half car's two "wheels" are
    # its two axles, each alone at its measured point

    @property
    def n_dof(self) -> int:
        """Number of degrees of freedom."""
        return 4

    @property
    def contact_dofs(self) -> NDArray[np.intp]:
        """DOF index of each wheel (axle)."""
        return np.array([2, 3])

    @property
    def contact_k(self) -> NDArray[np.float64]:
        """Contact stiffness of each wheel (axle), N/m."""
        return np.array([self.kt1, self.kt2])

    @property
    def wheel_offsets_m(self) -> NDArray[np.float64]:
        """Position of each wheel (axle) ahead of the body centre, m."""
        return np.array([self.d1, -self.d2])

    @property
    def axle_wheels(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """The wheels making up the front and rear measured point."""
        return (0,), (1,)

    @property
    def axle_wheel_offsets_m(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Each wheel of a measured point relative to it, m."""
        return (0.0,), (0.0,)

    def gravity_load(self, g: float = GRAVITY) -> NDArray[np.float64]:
        """Weight on each DOF, N (negative: down)."""
        return -g * np.array([self.ms, 0.0, self.mu1, self.mu2])

    def static_wheel_loads(self, g: float = GRAVITY) -> NDArray[np.float64]:
        """Static contact force of each wheel (axle), N (compression > 0)."""
        return np.array(self.static_axle_loads(g))

    def axle_input(self) -> NDArray[np.float64]:
        """Force on each DOF per unit rail level (m) under axle 1 and axle 2, N/m, (4, 2)."""
        F = np.zeros((4, 2))
        F[2, 0], F[3, 1] = self.kt1, self.kt2
        return F

    def masses(self) -> NDArray[np.float64]:
        """Mass (kg) or inertia (kg m²) of each DOF ``[u_s, theta_s, u_u1, u_u2]``."""
        return np.array([self.ms, self.Is, self.mu1, self.mu2])

    def suspension_links(self) -> list[Link]:
        """Suspension ``i`` links the body point above axle ``i`` (``u_s + d1 theta_s`` or
        ``u_s - d2 theta_s``) to the axle."""
        return [
            (np.array([1.0, self.d1, -1.0, 0.0]), self.ks1, self.cs1),
            (np.array([1.0, -self.d2, 0.0, -1.0]), self.ks2, self.cs2),
        ]


class VehicleModel(Protocol):
    """What every vehicle kind gives the forward model and the inversion (per rail, SI).

    The DOFs start with the body's bounce (m) and pitch (rad, nose-up); each wheel is one
    contact spring on one DOF; the inversion measures two points (the half car's axles, a
    bogie vehicle's bogie centres), ``d1`` ahead of and ``d2`` behind the body centre, each
    the mean of its wheels' levels.
    """

    kind: ClassVar[str]
    rails: ClassVar[int]
    """Rails the parameters (a payload, a whole-vehicle mass) describe; the model is one."""

    @property
    def d1(self) -> float: ...
    @property
    def d2(self) -> float: ...
    @property
    def ms(self) -> float: ...
    @property
    def sensor_x_m(self) -> float: ...
    @property
    def wheelbase(self) -> float: ...
    @property
    def n_dof(self) -> int: ...
    @property
    def contact_dofs(self) -> NDArray[np.intp]: ...
    @property
    def contact_k(self) -> NDArray[np.float64]: ...
    @property
    def wheel_offsets_m(self) -> NDArray[np.float64]: ...
    @property
    def axle_wheels(self) -> tuple[tuple[int, ...], tuple[int, ...]]: ...
    @property
    def axle_wheel_offsets_m(self) -> tuple[tuple[float, ...], tuple[float, ...]]: ...
    def matrices(
        self,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]: ...
    def gravity_load(self, g: float = GRAVITY) -> NDArray[np.float64]: ...
    def static_wheel_loads(self, g: float = GRAVITY) -> NDArray[np.float64]: ...
    def static_axle_loads(self, g: float = GRAVITY) -> tuple[float, float]: ...
    def axle_input(self) -> NDArray[np.float64]: ...
    def to_dict(self) -> dict[str, Any]: ...


TABLE1 = VehicleParams()
"""The paper's Table 1 vehicle."""

HEAVY = VehicleParams(
    ms=36000.0, Is=282240.0, mu1=2000.0, mu2=2000.0, ks1=1.6e6, ks2=1.6e6, cs1=40e3,
    cs2=40e3, kt1=5e6, kt2=5e6, d1=4.5, d2=4.5,
)  # fmt: skip
"""A heavy vehicle with about twice Table 1's wheel load (≈ 196 kN per axle): the heavy
vehicle of the public geometry set (shared/data/geometry, ``vehicle_key`` B)."""

PRESETS: dict[str, VehicleParams] = {"table1": TABLE1, "heavy": HEAVY}
"""Vehicle presets by name; selectable wherever a vehicle is (CLI ``--vehicle``, API)."""


def get_preset(name: str) -> VehicleParams:
    """A vehicle preset by name; :class:`ParameterError` naming the known ones otherwise."""
    try:
        return PRESETS[name]
    except (KeyError, TypeError):
        raise ParameterError(
            f"unknown vehicle preset {name!r}; expected one of {sorted(PRESETS)}"
        ) from None
