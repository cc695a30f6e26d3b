"""The bogie vehicle: a car body on two bogies, each a frame on two wheelsets.

The model is the one-rail (per-rail) model the track is: the whole-vehicle datasheet values
(masses and inertias of the whole body, bogie frame and wheelset; secondary per bogie side;
primary per axle box; contact per wheel) are turned into per-rail values by halving the masses
and inertias; a bogie side's secondary, an axle box's primary and a wheel's contact spring
already carry one rail's share.

Degrees of freedom (per rail; displacements m positive up, pitches rad positive nose-up):
``[z_c, th_c, z_b1, th_b1, z_b2, th_b2, z_w1, z_w2, z_w3, z_w4]``: body bounce and pitch,
front bogie bounce and pitch, rear bogie bounce and pitch, the four wheels in the order front
bogie front, front bogie rear, rear bogie front, rear bogie rear. The bogie centres sit
``bogie_half_spacing_m`` ahead of and behind the body centre of gravity, the wheelsets half
the wheelbase ahead of and behind their bogie's centre.

For the inversion the two wheels of a bogie act as one input: with equal primaries and wheel
masses the sum of a bogie's two wheel equations does not contain the frame's pitch, so the
body (and the frame's bounce) respond to the *mean* of the two wheels' rail levels only. The
bogie centre is then the measured point (the half car's "axle"), and the level recovered is
the bogie-mean level.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from .errors import ParameterError
from .vehicle import GRAVITY, Link, VehicleKindBase, VehicleParams, _param

N_DOF = 10
"""Degrees of freedom of the per-rail bogie vehicle."""

WHEEL_DOFS = np.arange(6, 10)
"""Index of each wheel's DOF (front bogie front, front bogie rear, rear bogie front, rear)."""


@dataclass(frozen=True)
class BogieParams(VehicleKindBase):
    """A four-axle bogie vehicle as its datasheet gives it (whole vehicle, SI).

    Parameters
    ----------
    body_mass_kg : float
        Car body mass (with its payload), kg.
    body_pitch_inertia_kgm2 : float
        Body pitch inertia about its centre of gravity, kg m².
    bogie_mass_kg : float
        Mass of one bogie frame (without wheelsets), kg.
    bogie_pitch_inertia_kgm2 : float
        Pitch inertia of one bogie frame, kg m².
    wheelset_mass_kg : float
        Mass of one wheelset, kg.
    bogie_half_spacing_m : float
        Half the distance between the bogie centres, m (body centre to each bogie centre).
    wheelbase_m : float
        Distance between a bogie's two wheelsets, m.
    secondary_k_n_per_m, secondary_c_ns_per_m : float
        Secondary suspension stiffness (N/m) and damping (N s/m) per bogie side.
    primary_k_n_per_m, primary_c_ns_per_m : float
        Primary suspension stiffness (N/m) and damping (N s/m) per axle box.
    contact_k_n_per_m : float
        Linearised wheel-rail contact stiffness per wheel, N/m.
    sensor_x_m : float
        Accelerometer position ahead of the body centre, m (it measures ``ü_c + x θ̈_c``).

    Raises
    ------
    ParameterError
        ``field=<name>``: a value is not a number, not finite, or outside its physical range.
    """

    kind: ClassVar[str] = "bogie"
    what: ClassVar[str] = "bogie-vehicle parameter"
    rails: ClassVar[int] = 2
    """The datasheet is the whole vehicle: both rails."""

    body_mass_kg: float = _param(27000.0, "kg", "Car body mass", bounds=(1000.0, 2e5))
    body_pitch_inertia_kgm2: float = _param(
        1.62e6, "kg m²", "Body pitch inertia", bounds=(1e3, 1e8)
    )
    bogie_mass_kg: float = _param(2600.0, "kg", "Bogie frame mass (each)", bounds=(100.0, 2e4))
    bogie_pitch_inertia_kgm2: float = _param(
        2100.0, "kg m²", "Bogie frame pitch inertia (each)", bounds=(10.0, 1e5)
    )
    wheelset_mass_kg: float = _param(1350.0, "kg", "Wheelset mass (each)", bounds=(100.0, 5000.0))
    bogie_half_spacing_m: float = _param(
        9.5, "m", "Half the bogie centre distance", bounds=(1.0, 15.0)
    )
    wheelbase_m: float = _param(2.6, "m", "Bogie wheelbase", bounds=(0.5, 4.5))
    secondary_k_n_per_m: float = _param(
        0.36e6, "N/m", "Secondary stiffness per bogie side", bounds=(1e4, 1e9)
    )
    secondary_c_ns_per_m: float = _param(
        24e3, "N s/m", "Secondary damping per bogie side", "nonnegative", (0.0, 1e7)
    )
    primary_k_n_per_m: float = _param(
        0.95e6, "N/m", "Primary stiffness per axle box", bounds=(1e4, 1e10)
    )
    primary_c_ns_per_m: float = _param(
        12e3, "N s/m", "Primary damping per axle box", "nonnegative", (0.0, 1e7)
    )
    contact_k_n_per_m: float = _param(
        1.04e9, "N/m", "Linearised contact stiffness per wheel", bounds=(1e6, 1e11)
    )
    sensor_x_m: float = _param(
        0.0, "m", "Accelerometer position from the body centre, towards the front bogie",
        "position",
    )  # fmt: skip

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.wheelbase_m / 2 >= self.bogie_half_spacing_m:
            raise ParameterError(
                f"vehicle parameter wheelbase_m ({self.wheelbase_m:g} m) must be shorter than "
                f"the bogie centre distance (2 x bogie_half_spacing_m = "
                f"{2 * self.bogie_half_spacing_m:g} m)",
                field="wheelbase_m",
            )

    def to_dict(self) -> dict[str, Any]:
        """Parameters as a plain dict (SI units), with ``kind``."""
        return {"kind": self.kind, **asdict(self)}

    def with_body_mass(self, ms: float) -> BogieParams:
        """The vehicle with another per-rail body mass ``ms``, kg (the half car's ``ms``
        convention: the whole body is twice it); the pitch inertia scales with it."""
        body = 2.0 * ms
        return self.replace(
            body_mass_kg=body,
            body_pitch_inertia_kgm2=self.body_pitch_inertia_kgm2 * body / self.body_mass_kg,
        )

    # -- per-rail values -------------------------------------------------------------------

    @property
    def ms(self) -> float:
        """Per-rail body mass, kg (half the body)."""
        return 0.5 * self.body_mass_kg

    @property
    def d1(self) -> float:
        """Body centre to the front bogie centre (the measured point), m."""
        return self.bogie_half_spacing_m

    @property
    def d2(self) -> float:
        """Body centre to the rear bogie centre, m."""
        return self.bogie_half_spacing_m

    @property
    def wheelbase(self) -> float:
        """Distance between the two measured points (bogie centres), m."""
        return 2.0 * self.bogie_half_spacing_m

    @property
    def n_dof(self) -> int:
        """Number of degrees of freedom."""
        return N_DOF

    @property
    def contact_dofs(self) -> NDArray[np.intp]:
        """DOF index of each wheel."""
        return WHEEL_DOFS.copy()

    @property
    def contact_k(self) -> NDArray[np.float64]:
        """Contact stiffness of each wheel, N/m."""
        return np.full(4, self.contact_k_n_per_m)

    @property
    def wheel_offsets_m(self) -> NDArray[np.float64]:
        """Position of each wheel ahead of the body centre, m."""
        L, a = self.bogie_half_spacing_m, 0.5 * self.wheelbase_m
        return np.array([L + a, L - a, -L + a, -L - a])

    @property
    def axle_wheels(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """The wheels making up the front and rear measured point (their mean is measured)."""
        return (0, 1), (2, 3)

    @property
    def axle_wheel_offsets_m(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Each wheel of a measured point relative to it, m (the stiffness fit's load)."""
        a = 0.5 * self.wheelbase_m
        return (a, -a), (a, -a)

    def masses(self) -> NDArray[np.float64]:
        """Per-rail mass (kg) or inertia (kg m²) of each DOF."""
        mb, ib, mw = (
            0.5 * self.bogie_mass_kg,
            0.5 * self.bogie_pitch_inertia_kgm2,
            0.5 * (self.wheelset_mass_kg),
        )
        return np.array(
            [self.ms, 0.5 * self.body_pitch_inertia_kgm2, mb, ib, mb, ib, mw, mw, mw, mw]
        )

    def gravity_load(self, g: float = GRAVITY) -> NDArray[np.float64]:
        """Weight on each DOF, N (negative: down); zero on the pitches."""
        m = self.masses()
        m[[1, 3, 5]] = 0.0
        return -g * m

    def static_wheel_loads(self, g: float = GRAVITY) -> NDArray[np.float64]:
        """Static contact force of each wheel on one rail, N (compression > 0)."""
        m = self.masses()
        return np.full(4, g * (0.25 * m[0] + 0.5 * m[2] + m[6]))

    def static_axle_loads(self, g: float = GRAVITY) -> tuple[float, float]:
        """Static load of each measured point (a bogie: both its wheels), N."""
        w = self.static_wheel_loads(g)
        return float(w[0] + w[1]), float(w[2] + w[3])

    def axle_input(self) -> NDArray[np.float64]:
        """Force on each DOF per unit rail level (m) under the front and rear measured point,
        N/m, shape (10, 2): both wheels of a bogie see its (mean) level."""
        F = np.zeros((N_DOF, 2))
        F[[6, 7], 0] = self.contact_k_n_per_m
        F[[8, 9], 1] = self.contact_k_n_per_m
        return F

    def suspension_links(self) -> list[Link]:
        """Each bogie side's secondary links the body point above the bogie centre to the
        frame; each axle box's primary links the frame point above the wheel to the wheel."""
        L, a = self.bogie_half_spacing_m, 0.5 * self.wheelbase_m
        links: list[Link] = []
        ks, cs = self.secondary_k_n_per_m, self.secondary_c_ns_per_m
        kp, cp = self.primary_k_n_per_m, self.primary_c_ns_per_m
        for b, sign in ((2, 1.0), (4, -1.0)):
            v = np.zeros(N_DOF)
            v[[0, 1, b]] = 1.0, sign * L, -1.0  # body point above the bogie centre - bogie
            links.append((v, ks, cs))
        for w, (b, sign) in enumerate(((2, 1.0), (2, -1.0), (4, 1.0), (4, -1.0))):
            v = np.zeros(N_DOF)
            v[[b, b + 1, 6 + w]] = 1.0, sign * a, -1.0  # frame point above the wheel - wheel
            links.append((v, kp, cp))
        return links

    def lumped_half_car(self) -> VehicleParams:
        """The half car a user would map this vehicle onto (each bogie one axle): body per
        rail; axle = frame + its two wheels; suspension = the secondary in series with the
        two primaries (static value; damping the secondary's); contact = the two wheels'
        springs in parallel. An approximation (the bogie's own dynamics and its wheelbase are
        lost), kept where a half-car parameter set is wanted."""
        ks, kp = self.secondary_k_n_per_m, 2 * self.primary_k_n_per_m
        mu = 0.5 * self.bogie_mass_kg + self.wheelset_mass_kg
        k = ks * kp / (ks + kp)
        return VehicleParams(
            ms=self.ms, Is=0.5 * self.body_pitch_inertia_kgm2, mu1=mu, mu2=mu, ks1=k, ks2=k,
            cs1=self.secondary_c_ns_per_m, cs2=self.secondary_c_ns_per_m,
            kt1=2 * self.contact_k_n_per_m, kt2=2 * self.contact_k_n_per_m,
            d1=self.bogie_half_spacing_m, d2=self.bogie_half_spacing_m, sensor_x_m=self.sensor_x_m,
        )  # fmt: skip

    def derived(self, g: float = GRAVITY) -> dict[str, float]:
        """The whole-vehicle quantities a plausibility check looks at.

        Returns
        -------
        dict
            ``total_mass_kg`` (kg); ``static_wheel_load_n`` (N, per wheel);
            ``body_bounce_hz``, ``body_pitch_hz`` (body on each bogie's secondary in series
            with its two primaries, rigid track, Hz); ``bogie_bounce_hz``,
            ``bogie_pitch_hz`` (frame on its primaries and secondary, body and wheels held,
            Hz); ``static_deflection_m`` (sag of the body under its weight: secondary plus
            primaries, m); ``mode_1_hz`` .. ``mode_4_hz`` (the model's lowest four undamped
            natural frequencies, Hz).
        """
        m = self.masses()
        ks, kp = self.secondary_k_n_per_m, self.primary_k_n_per_m
        L, a = self.bogie_half_spacing_m, 0.5 * self.wheelbase_m
        k_series = ks * 2 * kp / (ks + 2 * kp)  # one bogie: secondary, then two primaries
        per_bogie = 0.5 * m[0] * g  # body weight on one bogie side, N
        two_pi = 2 * np.pi
        out = {
            "total_mass_kg": self.body_mass_kg + 2 * self.bogie_mass_kg
            + 4 * self.wheelset_mass_kg,
            "static_wheel_load_n": float(self.static_wheel_loads(g)[0]),
            "body_bounce_hz": float(np.sqrt(2 * k_series / m[0]) / two_pi),
            "body_pitch_hz": float(np.sqrt(2 * k_series * L**2 / m[1]) / two_pi),
            "bogie_bounce_hz": float(np.sqrt((2 * kp + ks) / m[2]) / two_pi),
            "bogie_pitch_hz": float(np.sqrt(2 * kp * a**2 / m[3]) / two_pi),
            "static_deflection_m": float(per_bogie / ks + (per_bogie + m[2] * g) / (2 * kp)),
        }  # fmt: skip
        M, _, K = self.matrices()
        lam = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
        for i, v in enumerate(lam[:4]):
            out[f"mode_{i + 1}_hz"] = float(np.sqrt(max(v, 0.0)) / two_pi)
        return out


PASSENGER_COACH = BogieParams()
"""A four-axle passenger coach, 37.6 t (values and sources in docs/method.md)."""

FREIGHT_WAGON = BogieParams(
    body_mass_kg=70200.0, body_pitch_inertia_kgm2=1.45e6, bogie_mass_kg=2200.0,
    bogie_pitch_inertia_kgm2=1000.0, wheelset_mass_kg=1350.0, bogie_half_spacing_m=6.3,
    wheelbase_m=1.9, secondary_k_n_per_m=25e6, secondary_c_ns_per_m=60e3,
    primary_k_n_per_m=1.6e6, primary_c_ns_per_m=35e3, contact_k_n_per_m=1.33e9,
)  # fmt: skip
"""A loaded four-axle freight wagon, 80 t (20 t axle load; docs/method.md)."""
