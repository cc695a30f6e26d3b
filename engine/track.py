"""Track description: UIC60 rail on discrete supports, soft zones and rail irregularity.

Chainage is the position along the track in metres. Supports (sleepers) stand at
``x_k = k * spacing`` for ``k = 0 .. n`` from chainage 0 to the track length.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import ParameterError, as_number, check_range, reject_unknown_keys

UIC60_E = 210e9
"""Young's modulus of rail steel, Pa."""
UIC60_I = 3.055e-5
"""Second moment of area of a UIC60 rail about the horizontal axis, m⁴."""
UIC60_MASS = 60.21
"""Mass of a UIC60 rail per metre, kg/m."""


@dataclass(frozen=True)
class SoftZone:
    """A stretch of track whose supports have lost part of their stiffness.

    Parameters
    ----------
    start_m, end_m : float
        Chainage of the first and last affected support, m (inclusive).
    loss : float
        Fraction of the nominal stiffness lost, 0 <= loss < 1 (0.4 is a 40 % loss).
    """

    start_m: float
    end_m: float
    loss: float

    def __post_init__(self) -> None:
        for name in ("start_m", "end_m", "loss"):
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v):
                raise ParameterError(f"soft zone {name} must be a finite number, got {v!r}")
        if self.end_m < self.start_m:
            raise ParameterError(
                f"soft zone end {self.end_m} m is before its start {self.start_m} m"
            )
        if not 0.0 <= self.loss < 1.0:
            raise ParameterError(
                f"soft zone stiffness loss must be a fraction in [0, 1), got {self.loss}"
            )

    @classmethod
    def parse(cls, text: str) -> SoftZone:
        """Parse ``"start:end:loss"`` (metres, metres, fraction), e.g. ``"60:65:0.5"``."""
        parts = text.split(":")
        if len(parts) != 3:
            raise ParameterError(
                f"soft zone {text!r} must be 'start_m:end_m:loss', e.g. '60:65:0.5'"
            )
        try:
            start, end, loss = (float(p) for p in parts)
        except ValueError:
            raise ParameterError(
                f"soft zone {text!r}: start, end (m) and loss (fraction) must be numbers"
            ) from None
        return cls(start, end, loss)


TRACK_RANGES: dict[str, tuple[float, float, str, str]] = {
    "spacing": (0.3, 1.5, "m", "support spacing"),
    "EI": (1e5, 1e8, "N m²", "rail bending stiffness"),
    "mass_per_m": (10.0, 200.0, "kg/m", "rail mass per metre"),
    "k_nominal": (5e6, 2e9, "N/m", "nominal support stiffness"),
    "c_support": (0.0, 1e7, "N s/m", "support damping"),
}
"""Physical range of each track parameter: ``(lowest, highest, unit, what)``, inclusive.

From light rail on closely spaced sleepers to heavy crane rail (EI of UIC60 is 6.4e6 N m²,
of a 49 kg/m rail 3.8e6), 5 to 2000 kN/mm per support. Outside these the model is not a
track (a 1 cm spacing made one inversion take 297 s; 1e-300 or 1e308 overflowed)."""


@dataclass(frozen=True)
class TrackParams:
    """Rail and support properties of a track (defaults: UIC60 on 80 kN/mm supports).

    Every parameter must lie in its physical range (:data:`TRACK_RANGES`).

    Parameters
    ----------
    spacing : float
        Support (sleeper) spacing, m.
    EI : float
        Rail bending stiffness, N m².
    mass_per_m : float
        Rail mass per unit length, kg/m.
    k_nominal : float
        Nominal support stiffness, N/m per support.
    c_support : float
        Support damping, N s/m per support.
    """

    spacing: float = 0.6
    EI: float = UIC60_E * UIC60_I
    mass_per_m: float = UIC60_MASS
    k_nominal: float = 8e7
    c_support: float = 5e4

    def __post_init__(self) -> None:
        for name, (lo, hi, unit, what) in TRACK_RANGES.items():
            value = as_number(getattr(self, name), name, f"track parameter {name}", unit)
            object.__setattr__(self, name, value)
            check_range(value, name, f"track parameter {name} ({what})", lo, hi, unit)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrackParams:
        """Build from a mapping; unknown keys are an error, missing keys take defaults."""
        reject_unknown_keys(data, cls.__dataclass_fields__, "track parameter")
        return cls(**data)

    def to_dict(self) -> dict[str, float]:
        """Parameters as a plain dict (SI units)."""
        return asdict(self)

    @property
    def winkler_modulus(self) -> float:
        """Equivalent continuous foundation modulus ``k_nominal / spacing``, N/m²."""
        return self.k_nominal / self.spacing

    def winkler_deflection(self, load: float, stiffness_factor: float = 1.0) -> float:
        """Static deflection of a continuous Winkler beam under a point load, m (positive down).

        ``P beta / (2 k')`` with ``k' = factor * k_nominal / spacing`` and
        ``beta = (k' / (4 EI))**0.25``.
        """
        kf = stiffness_factor * self.winkler_modulus
        beta = (kf / (4.0 * self.EI)) ** 0.25
        return load * beta / (2.0 * kf)


Irregularity = Callable[[NDArray[np.float64]], NDArray[np.float64]]
"""Rail irregularity: maps chainage (m) to unloaded rail level (m, positive up)."""


@dataclass(frozen=True)
class Track:
    """A finite track: its parameters, length and the stiffness of every support.

    Parameters
    ----------
    length : float
        Track length, m; supports stand at ``0, spacing, ... <= length``.
    params : TrackParams
        Rail and nominal support properties.
    support_stiffness : ndarray, optional
        Stiffness of each support, N/m. Default: built from ``k_nominal`` and ``zones``.
    zones : sequence of SoftZone
        Soft zones applied to the nominal stiffness (ignored if ``support_stiffness`` given).
    irregularity : callable or (x, r) arrays, optional
        Unloaded rail level ``r(x)``, m, positive up; arrays are interpolated linearly.
    """

    length: float
    params: TrackParams = field(default_factory=TrackParams)
    support_stiffness: NDArray[np.float64] | None = None
    zones: tuple[SoftZone, ...] = ()
    irregularity: Irregularity | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.length, int | float) and math.isfinite(self.length)):
            raise ParameterError(
                f"track length must be a finite number of metres, got {self.length!r}"
            )
        if self.length < 4 * self.params.spacing:
            raise ParameterError(f"track length {self.length} m is shorter than 4 support spacings")
        n = self.n_supports
        object.__setattr__(self, "zones", tuple(self.zones))
        if self.support_stiffness is None:
            k = np.full(n, self.params.k_nominal)
            x = self.support_x
            for z in self.zones:
                tol = 1e-9 * max(1.0, abs(z.end_m))
                k[(x >= z.start_m - tol) & (x <= z.end_m + tol)] *= 1.0 - z.loss
        else:
            k = np.array(self.support_stiffness, dtype=float)
            if k.shape != (n,):
                raise ParameterError(
                    f"support_stiffness must have one value per support ({n} for a "
                    f"{self.length} m track at {self.params.spacing} m spacing), "
                    f"got shape {k.shape}"
                )
            if not np.all(np.isfinite(k)) or np.any(k <= 0):
                i = int(np.flatnonzero(~np.isfinite(k) | (k <= 0))[0])
                raise ParameterError(
                    f"support_stiffness[{i}] = {k[i]} N/m: every support needs a finite "
                    "positive stiffness"
                )
        k.setflags(write=False)
        object.__setattr__(self, "support_stiffness", k)

    @property
    def n_supports(self) -> int:
        """Number of supports."""
        return int(math.floor(self.length / self.params.spacing + 1e-9)) + 1

    @property
    def support_x(self) -> NDArray[np.float64]:
        """Chainage of each support, m."""
        return np.arange(self.n_supports, dtype=np.float64) * self.params.spacing

    @property
    def k(self) -> NDArray[np.float64]:
        """Support stiffness array, N/m (read-only)."""
        assert self.support_stiffness is not None
        return self.support_stiffness

    def rail_irregularity(self, x: ArrayLike) -> NDArray[np.float64]:
        """Unloaded rail level at chainage ``x`` (m), in m; zero without irregularity."""
        xa = np.asarray(x, dtype=float)
        if self.irregularity is None:
            return np.zeros_like(xa)
        return np.asarray(self.irregularity(xa), dtype=float)


def irregularity_from_samples(x: ArrayLike, r: ArrayLike) -> Irregularity:
    """Rail irregularity interpolated linearly from samples ``(x (m), r (m))``."""
    xa = np.asarray(x, dtype=float)
    ra = np.asarray(r, dtype=float)
    if xa.ndim != 1 or xa.shape != ra.shape or xa.size < 2:
        raise ParameterError("irregularity needs two 1-D arrays of equal length >= 2")
    if np.any(np.diff(xa) <= 0):
        raise ParameterError("irregularity chainages must be strictly increasing")

    def level(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.interp(q, xa, ra)

    return level
