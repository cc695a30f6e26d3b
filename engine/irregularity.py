"""Unloaded rail geometry (longitudinal level): standard spectra and random profiles.

A spectrum is a one-sided power spectral density ``S(Omega)`` of the vertical rail level,
m²/(rad/m), against the spatial angular frequency ``Omega = 2 pi / lambda`` (rad/m). A random
profile with that spectrum is a sum of cosines with random phases and amplitudes
``sqrt(2 S(Omega_k) dOmega)`` (inverse FFT), limited to the wavelengths the forward model
resolves (1-120 m by default). Sources and formulas: docs/method.md, "Rail geometry".

Registry :data:`SPECTRA`: ``german-low``, ``german-high`` (the German high-speed spectra,
low and high disturbance) and ``fra-1`` .. ``fra-6`` (US FRA track classes; class 6 is the
best track). Constants are stored in SI (m² rad/m); the FRA tables give ``A_v`` in
cm² rad/m, converted here once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.fft as sfft
from numpy.typing import ArrayLike, NDArray

from .errors import ParameterError
from .track import Irregularity, irregularity_from_samples

LAMBDA_MIN_M = 1.0
"""Shortest wavelength of generated profiles by default, m (the model's resolution)."""
LAMBDA_MAX_M = 120.0
"""Longest wavelength of generated profiles by default, m."""


@dataclass(frozen=True)
class Spectrum:
    """A standard one-sided rail-level spectrum ``S(Omega)``, m²/(rad/m).

    ``form == "german"``: ``S = A_v Omega_c² / ((Omega² + Omega_r²)(Omega² + Omega_c²))``.
    ``form == "fra"``: ``S = k A_v Omega_c² / (Omega² (Omega² + Omega_c²))``.

    Parameters
    ----------
    name : str
        Registry key.
    form : {"german", "fra"}
        Formula (above).
    a_v : float
        Roughness constant ``A_v``, m² rad/m.
    omega_c : float
        Cut-off frequency ``Omega_c``, rad/m.
    omega_r : float
        Second corner ``Omega_r``, rad/m (German form only).
    k : float
        Safety/shape factor ``k`` (FRA form, 0.25).
    source : str
        Where the constants come from.
    """

    name: str
    form: str
    a_v: float
    omega_c: float
    omega_r: float = 0.0
    k: float = 1.0
    source: str = ""

    def psd(self, omega: ArrayLike) -> NDArray[np.float64]:
        """One-sided PSD at ``omega`` (rad/m, > 0), m²/(rad/m)."""
        w2 = np.asarray(omega, dtype=float) ** 2
        oc2 = self.omega_c**2
        if self.form == "german":
            return self.a_v * oc2 / ((w2 + self.omega_r**2) * (w2 + oc2))
        with np.errstate(divide="ignore"):
            return self.k * self.a_v * oc2 / (w2 * (w2 + oc2))

    def sd_m(self, lambda_min_m: float, lambda_max_m: float) -> float:
        """Standard deviation of the level in a wavelength band, m (integral of the PSD)."""
        w = np.geomspace(2 * np.pi / lambda_max_m, 2 * np.pi / lambda_min_m, 4001)
        s = self.psd(w)
        return float(math.sqrt(np.sum(0.5 * (s[1:] + s[:-1]) * np.diff(w))))


_GERMAN = "German high-speed track spectra (ORE B176 / DB), as cited in geometry.md and Zhai, "
_GERMAN += "Vehicle-Track Coupled Dynamics (2020), table 'German high-speed track spectra'"
_FRA = "US FRA track classes (Hamid & Yang; Zhai, Vehicle-Track Coupled Dynamics): "
_FRA += "A_v in cm² rad/m converted to m² rad/m, Omega_c = 0.8245 rad/m, k = 0.25"
_FRA_AV_CM2 = {1: 1.2107, 2: 1.0181, 3: 0.6816, 4: 0.5376, 5: 0.2095, 6: 0.0339}

SPECTRA: dict[str, Spectrum] = {
    "german-low": Spectrum("german-low", "german", 4.032e-7, 0.8246, 0.0206, source=_GERMAN),
    "german-high": Spectrum("german-high", "german", 1.080e-6, 0.8246, 0.0206, source=_GERMAN),
    **{
        f"fra-{c}": Spectrum(f"fra-{c}", "fra", av * 1e-4, 0.8245, k=0.25, source=_FRA)
        for c, av in _FRA_AV_CM2.items()
    },
}
"""Standard spectra by name (see :class:`Spectrum`)."""


def get_spectrum(name: str | Spectrum) -> Spectrum:
    """A spectrum by registry name (or the spectrum itself); clear error if unknown."""
    if isinstance(name, Spectrum):
        return name
    try:
        return SPECTRA[name]
    except (KeyError, TypeError):
        raise ParameterError(
            f"unknown irregularity spectrum {name!r}; expected one of {sorted(SPECTRA)}"
        ) from None


@dataclass(frozen=True)
class Profile:
    """An unloaded rail-level profile sampled on a regular grid.

    Attributes
    ----------
    x_m : ndarray
        Chainage, m, increasing.
    level_m : ndarray
        Unloaded rail level, m, positive up.
    spectrum : str
        Spectrum name, or ``"given"`` for a profile read from data.
    seed : int or None
        Seed of the random phases.
    """

    x_m: NDArray[np.float64]
    level_m: NDArray[np.float64]
    spectrum: str = "given"
    seed: int | None = None

    def as_irregularity(self) -> Irregularity:
        """The profile as the forward model's irregularity function (linear interpolation)."""
        return irregularity_from_samples(self.x_m, self.level_m)

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.interp(x, self.x_m, self.level_m)


def random_profile(
    spectrum: str | Spectrum,
    length_m: float,
    *,
    seed: int | None = None,
    step_m: float = 0.05,
    lambda_min_m: float = LAMBDA_MIN_M,
    lambda_max_m: float = LAMBDA_MAX_M,
    scale: float = 1.0,
) -> Profile:
    """A random unloaded rail profile with a standard spectrum, from chainage 0 to ``length_m``.

    Parameters
    ----------
    spectrum : str or Spectrum
        Registry name (:data:`SPECTRA`) or a spectrum.
    length_m : float
        Length covered, m.
    seed : int, optional
        Seed of the random phases (same seed, same profile).
    step_m : float
        Sample spacing, m (<= lambda_min_m / 8).
    lambda_min_m, lambda_max_m : float
        Wavelengths kept, m.
    scale : float
        Multiplier of the amplitudes (e.g. 0.5 for half the spectrum's level).

    Returns
    -------
    Profile
        Level in m, positive up, zero mean.
    """
    spec = get_spectrum(spectrum)
    if not (math.isfinite(length_m) and length_m > 0):
        raise ParameterError(f"irregularity length must be > 0 m, got {length_m}")
    if not (0 < lambda_min_m < lambda_max_m):
        raise ParameterError(
            f"irregularity band must satisfy 0 < lambda_min_m < lambda_max_m, got "
            f"{lambda_min_m} m, {lambda_max_m} m"
        )
    if not (0 < step_m <= lambda_min_m / 8):
        raise ParameterError(
            f"irregularity step_m must be in (0, {lambda_min_m / 8:g}] m, got {step_m}"
        )
    if not (math.isfinite(scale) and scale >= 0):
        raise ParameterError(f"irregularity scale must be >= 0, got {scale}")
    n_out = int(math.ceil(length_m / step_m)) + 1
    # a period of at least 4 of the longest wavelengths: fine enough frequency resolution
    n = sfft.next_fast_len(max(n_out, int(math.ceil(4 * lambda_max_m / step_m))), real=True)
    omega = 2 * np.pi * sfft.rfftfreq(n, step_m)
    d_omega = 2 * np.pi / (n * step_m)
    keep = (omega >= 2 * np.pi / lambda_max_m) & (omega <= 2 * np.pi / lambda_min_m)
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0.0, 2 * np.pi, omega.size)
    amp = np.zeros(omega.size)
    amp[keep] = scale * np.sqrt(2.0 * spec.psd(omega[keep]) * d_omega)
    # irfft(X)[m] = (1/n) sum X_k e^{i omega_k x_m} (both halves): X_k = n/2 a_k e^{i phi}
    level = sfft.irfft(0.5 * n * amp * np.exp(1j * phase), n)[:n_out]
    x = np.arange(n_out, dtype=np.float64) * step_m
    return Profile(x, level - level.mean(), spec.name, seed)


def read_profile_csv(path: str | Path) -> Profile:
    """A given profile from CSV: header, then ``chainage_m,level_mm`` rows.

    Raises
    ------
    ParameterError
        Naming the row and column when a value is not a number or chainage does not increase.
    """
    p = Path(path)
    rows = p.read_text().splitlines()
    if len(rows) < 3:
        raise ParameterError(f"{p.name}: irregularity CSV needs a header and >= 2 rows")
    xs: list[float] = []
    ys: list[float] = []
    for i, line in enumerate(rows[1:], start=2):
        if not line.strip():
            continue
        parts = line.split(",")
        if len(parts) < 2:
            raise ParameterError(f"{p.name} row {i}: expected 'chainage_m,level_mm', got {line!r}")
        for col, (name, unit) in enumerate((("chainage_m", "m"), ("level_mm", "mm"))):
            try:
                v = float(parts[col])
            except ValueError:
                v = float("nan")
            if not math.isfinite(v):
                raise ParameterError(
                    f"{p.name} row {i}, column {name}: {parts[col]!r} is not a finite number "
                    f"of {unit}"
                )
            (xs if col == 0 else ys).append(v)
    return profile_from_samples(xs, np.asarray(ys) * 1e-3)


def profile_from_samples(x_m: ArrayLike, level_m: ArrayLike) -> Profile:
    """A given profile from arrays: chainage (m, strictly increasing), level (m, up)."""
    xa = np.asarray(x_m, dtype=float)
    ra = np.asarray(level_m, dtype=float)
    if xa.ndim != 1 or xa.shape != ra.shape or xa.size < 2:
        raise ParameterError("irregularity needs chainage and level arrays of equal length >= 2")
    if not (np.all(np.isfinite(xa)) and np.all(np.isfinite(ra))):
        raise ParameterError("irregularity chainage and level must be finite numbers")
    bad = np.flatnonzero(np.diff(xa) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise ParameterError(
            f"irregularity chainage must increase: value {i} ({xa[i]} m) does not follow "
            f"{xa[i - 1]} m"
        )
    return Profile(xa, ra)


def band_sd_mm(
    x_m: NDArray[np.float64],
    level_m: NDArray[np.float64],
    lambda_min_m: float = 3.0,
    lambda_max_m: float = 25.0,
) -> float:
    """Standard deviation of a profile's level in a wavelength band, mm (resampled to 0.25 m)."""
    from .chainage import bandpass_distance

    grid = np.arange(x_m[0], x_m[-1], 0.25)
    y = bandpass_distance(np.interp(grid, x_m, level_m) * 1e3, 0.25, lambda_min_m, lambda_max_m)
    return float(np.nanstd(y))
