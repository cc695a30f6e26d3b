"""Track quality in EN 13848 terms: longitudinal level in the D1/D2 bands, section statistics,
isolated defects against speed-class limits, repeatability and the trend to the next limit.

Input is a longitudinal level on a regular chainage grid (mm, positive up): the unloaded
geometry where the two-load separation holds, else the loaded level (the caller says which).
Everything here is pure numerics; units are m for chainage and wavelengths, mm for levels,
km/h for line speeds, days for time spans.

The wavelength filters follow EN 13848-1's definition of the bands (D1: 3 m < lambda <= 25 m,
D2: 25 m < lambda <= 70 m) as a zero-phase Butterworth band-pass: a high-pass and a low-pass of
order :data:`FILTER_ORDER` each, run forwards and backwards (``scipy.signal.sosfiltfilt``), the
design cut-offs placed so that the *zero-phase* gain is -3 dB at the band limits. The
standard's text was not available to check the order and the attenuation at the limits
against; both are fields of :class:`BandFilter` (see docs/method.md).

The line speeds, the limit tables and the isolated defects are in :mod:`engine.quality_limits`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import datetime, timedelta
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal
from scipy import stats as sstats

from .errors import InversionError, ParameterError
from .intervals import true_runs
from .methods import METHODS, MethodInput
from .pipeline import fuse_axles
from .setup import Method, PreparedRun
from .spectral import vehicle_response
from .vehicle import VehicleModel

FILTER_ORDER = 4
"""Order of each Butterworth half (high-pass, low-pass) of a band filter, per direction."""

CUTOFF_DB = 3.0
"""Attenuation of the zero-phase filter at the band limits, dB."""


@dataclass(frozen=True)
class BandFilter:
    """A zero-phase Butterworth band-pass over wavelengths ``lambda_min_m..lambda_max_m``.

    Parameters
    ----------
    name : str
        Band name (``D1``, ``D2``).
    lambda_min_m, lambda_max_m : float
        Band limits, m: the zero-phase gain there is ``-cutoff_db``.
    order : int
        Order of the high-pass and of the low-pass half, each run forwards and backwards.
    cutoff_db : float
        Attenuation at the band limits of the forward-backward filter, dB (> 0).
    """

    name: str
    lambda_min_m: float
    lambda_max_m: float
    order: int = FILTER_ORDER
    cutoff_db: float = CUTOFF_DB

    def __post_init__(self) -> None:
        if not (0 < self.lambda_min_m < self.lambda_max_m):
            raise ParameterError(
                f"band {self.name}: need 0 < lambda_min_m < lambda_max_m, got "
                f"{self.lambda_min_m} m, {self.lambda_max_m} m",
                field="lambda_min_m",
            )
        if not (1 <= self.order <= 10):
            raise ParameterError(
                f"band {self.name}: order {self.order} not in 1..10", field="order"
            )
        if not (0 < self.cutoff_db < 20):
            raise ParameterError(
                f"band {self.name}: cutoff_db {self.cutoff_db} not in (0, 20)", field="cutoff_db"
            )

    def _design_shift(self) -> float:
        # Each direction contributes half the attenuation: |H|^2 of one pass at the band limit
        # is 10^(-cutoff_db/20); for a Butterworth half that places the design frequency a
        # factor r^(1/2n) beyond the limit, r = 1/|H|^2 - 1.
        r = 1.0 / 10 ** (-self.cutoff_db / 20.0) - 1.0
        return float(r ** (-1.0 / (2 * self.order)))

    def sos(self, step_m: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Second-order sections of the high-pass and the low-pass half for grid ``step_m`` (m)
        (designed once per band and grid: a design costs more than filtering 10 km)."""
        return _designed(self, float(step_m))

    def _design(self, step_m: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        fs = 1.0 / step_m
        shift = self._design_shift()
        # scipy's bilinear design keeps the Butterworth law in tan(pi f / fs): shift there, so
        # the gain at the band limits is exact on any grid
        if (
            1.0 / self.lambda_min_m >= 0.5 * fs
            or math.tan(math.pi * step_m / self.lambda_min_m) * shift >= 1e3
        ):
            raise ParameterError(
                f"band {self.name}: a {step_m} m grid cannot hold {self.lambda_min_m} m waves "
                f"(needs a step below {0.5 * self.lambda_min_m:.3f} m)",
                field="step_m",
            )
        f_hp = math.atan(math.tan(math.pi * step_m / self.lambda_max_m) / shift) / (
            math.pi * step_m
        )
        f_lp = math.atan(math.tan(math.pi * step_m / self.lambda_min_m) * shift) / (
            math.pi * step_m
        )
        if f_lp >= 0.5 * fs:
            raise ParameterError(
                f"band {self.name}: a {step_m} m grid cannot hold {self.lambda_min_m} m waves "
                f"(needs a step below {0.5 / f_lp:.3f} m)",
                field="step_m",
            )
        hp = signal.butter(self.order, f_hp, btype="highpass", fs=fs, output="sos")
        lp = signal.butter(self.order, f_lp, btype="lowpass", fs=fs, output="sos")
        return np.asarray(hp, dtype=np.float64), np.asarray(lp, dtype=np.float64)

    def transfer(self, wavelength_m: ArrayLike, step_m: float = 0.25) -> NDArray[np.float64]:
        """Gain of the zero-phase filter at the given wavelengths (m), as applied on a grid
        of ``step_m`` (m): real, 0..1, no phase."""
        lam = np.asarray(wavelength_m, dtype=np.float64)
        g = np.ones_like(lam)
        for sos in self.sos(step_m):
            _, h = signal.sosfreqz(sos, worN=1.0 / lam.ravel(), fs=1.0 / step_m)
            g = g * (np.abs(h) ** 2).reshape(lam.shape)
        return g

    def apply(self, level_mm: ArrayLike, step_m: float) -> NDArray[np.float64]:
        """The level filtered to the band (mm), segment by segment between NaN gaps.

        Each segment is padded by odd reflection over one ``lambda_max_m`` before the
        forward-backward pass; segments shorter than ``lambda_max_m`` are left NaN (the band
        is not defined on them).
        """
        y = np.asarray(level_mm, dtype=np.float64)
        out = np.full_like(y, np.nan)
        halves = self.sos(step_m)
        sos = np.vstack(halves)
        ok = np.isfinite(y)
        min_n = int(math.ceil(self.lambda_max_m / step_m))
        for a, b in true_runs(ok):
            n = b - a
            if n < min_n:
                continue
            seg = y[a:b] - y[a:b].mean()
            pad = min(n - 1, int(math.ceil(1.5 * self.lambda_max_m / step_m)))
            out[a:b] = signal.sosfiltfilt(sos, seg, padtype="odd", padlen=pad)
        return out


@functools.lru_cache(maxsize=64)
def _designed(band: BandFilter, step_m: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    halves = band._design(step_m)
    for h in halves:
        h.flags.writeable = False  # shared between callers
    return halves


END_TRIM_M = 25.0
"""Stretch at each end of a level's coverage whose band-filtered values are not used, m: an
inversion's level rings near the ends of a run (errors up to 2.4 mm in D1 within 10 m of an
end, 0.8 mm within 25 m, 0.1 mm beyond, measured: docs/method.md)."""


def trim_ends(
    values: ArrayLike, step_m: float, margin_m: float = END_TRIM_M
) -> NDArray[np.float64]:
    """``values`` with NaN within ``margin_m`` (m) of each end of every finite stretch."""
    v = np.array(values, dtype=np.float64)
    ok = np.isfinite(v)
    k = int(round(margin_m / step_m))
    if k <= 0:
        return v
    for a, b in true_runs(ok):
        v[a : min(b, a + k)] = np.nan
        v[max(a, b - k) : b] = np.nan
    return v


BANDS: dict[str, BandFilter] = {
    "D1": BandFilter("D1", 3.0, 25.0),
    "D2": BandFilter("D2", 25.0, 70.0),
}
"""EN 13848-1's wavelength ranges of longitudinal level, by name."""


LONG_LEVEL_LAMBDA_MAX_M = 100.0
"""Longest wavelength of the loaded level D2 is filtered from, m: D2's 70 m with room for the
inversion band's taper. The stiffness separation keeps its own 40 m band: widened to 100 m it
holds the geometry within its limit at 41 % of the points instead of 83 % (docs/accuracy.md)."""

BAND_LEVEL: dict[str, str] = {"D1": "quality", "D2": "long"}
"""Which level each band is filtered from. ``quality``: the separated unloaded geometry where
separable, else the loaded level (3-40 m); ``long``: the passes' loaded level of a band
reaching :data:`LONG_LEVEL_LAMBDA_MAX_M` (25-70 m waves are the rail's long-wave geometry; the
deflection under the wheel varies over a few metres and adds little there: D2 SD per 200 m
within 0.015 mm of the truth's, measured: docs/accuracy.md)."""


LONG_LEVEL_METHOD: Method = "wiener"
"""Inversion of the long level, whatever the run's own method: the spectral inversion with its
Wiener weighting (any vehicle kind, one transform of the log; the least-squares fit would
double a slow run's cost for a level D2 needs only in its 25-70 m waves)."""


def long_level(run: PreparedRun) -> NDArray[np.float64] | None:
    """The run's loaded level in the band reaching :data:`LONG_LEVEL_LAMBDA_MAX_M`, mm.

    The run is inverted again with the same shortest wavelength and the longest one widened
    to :data:`LONG_LEVEL_LAMBDA_MAX_M` (:data:`LONG_LEVEL_METHOD`), on the run's own grid
    (``run.grid``, m); the two axles' levels fused as the result's level is
    (:func:`~engine.pipeline.fuse_axles`). D2 is filtered from it (:data:`BAND_LEVEL`).

    Returns
    -------
    ndarray or None
        Level on ``run.grid``, mm (NaN where no axle passed); None when the run is too
        short for the band (less than twice its longest wavelength).
    """
    cfg = run.setup.config
    if cfg.lambda_max_m >= LONG_LEVEL_LAMBDA_MAX_M:
        long_cfg = replace(cfg, method=LONG_LEVEL_METHOD)
    else:
        long_cfg = replace(cfg, method=LONG_LEVEL_METHOD, lambda_max_m=LONG_LEVEL_LAMBDA_MAX_M)
    try:
        wide = run.with_config(long_cfg)
    except InversionError:
        return None  # shorter than two longest wavelengths: no long level, D2 says so
    given = MethodInput(
        log=wide.log, positions=wide.positions, grid=wide.grid, step_m=long_cfg.grid_step_m,
        vehicle=wide.setup.vehicle, f_lo_hz=wide.f_lo_hz, f_hi_hz=wide.f_hi_hz,
        lambda_min_m=long_cfg.lambda_min_m, lambda_max_m=long_cfg.lambda_max_m,
        taper=long_cfg.taper,
    )  # fmt: skip
    inv = METHODS[long_cfg.method](given)
    return fuse_axles(inv.front_mm, inv.rear_mm)


def band_levels(
    levels: dict[str, NDArray[np.float64]], step_m: float, *, trim_m: float = 0.0
) -> tuple[dict[str, NDArray[np.float64]], dict[str, str]]:
    """Each band of :data:`BANDS` filtered from its level (:data:`BAND_LEVEL`), mm.

    Parameters
    ----------
    levels : dict
        Level name (``quality``, ``long``) -> level on one regular grid, mm (NaN = none).
        ``quality`` is required; a band whose own level is missing is filtered from it.
    step_m : float
        Grid step, m.
    trim_m : float
        Stretch at each end of a coverage left without a value (:func:`trim_ends`), m.

    Returns
    -------
    filtered : dict
        Band name -> filtered level, mm.
    used : dict
        Band name -> the level it was filtered from.
    """
    if "quality" not in levels:
        raise ParameterError("levels: the 'quality' level is required", field="levels")
    filtered, used = {}, {}
    for name, band in BANDS.items():
        src = BAND_LEVEL.get(name, "quality")
        src = src if src in levels else "quality"
        out = band.apply(levels[src], step_m)
        filtered[name] = trim_ends(out, step_m, trim_m) if trim_m > 0 else out
        used[name] = src
    return filtered, used


def get_band(name: str) -> BandFilter:
    """The band filter registered as ``name``; ParameterError listing the known ones."""
    try:
        return BANDS[name]
    except KeyError:
        raise ParameterError(
            f"unknown band {name!r}; known: {', '.join(BANDS)}", field="band"
        ) from None


# ----------------------------------------------------------------------------- observability


@dataclass(frozen=True)
class Observability:
    """What a car-body sensor (accelerometer + pitch gyro) sees of each wavelength.

    Attributes
    ----------
    wavelength_m : ndarray
        Wavelengths examined, m.
    gain : ndarray
        Combined sensitivity of the two signals to a unit profile at each wavelength, relative
        to its median over D1 (1 = typical; near 0 = the body does not move).
    bounce_nulls_m, pitch_nulls_m : tuple of float
        Wavelengths (3-70 m) at which the axle spacing cancels the body's bounce (the
        accelerometer at the centre sees nothing: ``2 L / (2 k + 1)``) or its pitch (the
        gyro sees nothing: ``L / k``), ``L`` the axle spacing (a bogie vehicle: the bogie
        centres' spacing), m.
    wheelbase_nulls_m : tuple of float
        Wavelengths (within the range examined) that a bogie's two wheelsets, ``a`` apart,
        cancel between them (``2 a / (2 k + 1)``): the bogie does not move, so neither does
        the body, m. Empty for a vehicle with one wheel per measured point.
    unobservable_m : tuple of (float, float)
        Wavelength ranges where ``gain`` is below ``threshold``: neither signal carries them
        above the noise, whatever the inversion does.
    speed_mps, threshold : float
        Speed the gains hold for (the suspension's frequency response), m/s; threshold used.
    """

    wavelength_m: NDArray[np.float64]
    gain: NDArray[np.float64]
    bounce_nulls_m: tuple[float, ...]
    pitch_nulls_m: tuple[float, ...]
    unobservable_m: tuple[tuple[float, float], ...]
    speed_mps: float
    threshold: float
    wheelbase_nulls_m: tuple[float, ...] = ()

    def to_dict(self) -> dict[str, object]:
        """Plain dict (no arrays) for answers and reports."""
        return {
            "speed_mps": self.speed_mps,
            "threshold": self.threshold,
            "bounce_nulls_m": list(self.bounce_nulls_m),
            "pitch_nulls_m": list(self.pitch_nulls_m),
            "wheelbase_nulls_m": list(self.wheelbase_nulls_m),
            "unobservable_m": [list(r) for r in self.unobservable_m],
        }


def observability(
    vehicle: VehicleModel,
    speed_mps: float,
    *,
    lambda_min_m: float = 3.0,
    lambda_max_m: float = 70.0,
    threshold: float = 0.05,
    n: int = 2000,
) -> Observability:
    """The wavelengths a car body on ``vehicle``'s suspension shows, at ``speed_mps`` (m/s).

    A profile ``e^{i 2 pi x / lambda}`` enters at both measured points (front ``d1`` ahead of
    the body centre, rear ``d2`` behind) as the mean over each point's wheels (a bogie's two
    wheelsets; a half car's one axle); :func:`engine.spectral.vehicle_response` gives the
    body's acceleration (at the sensor) and pitch rate. Each channel is scaled by its median
    over D1, so the combined gain says how well the pair sees a wavelength compared with the
    D1 band. Any vehicle kind (:class:`engine.vehicle.VehicleModel`).
    """
    if not (speed_mps > 0 and math.isfinite(speed_mps)):
        raise ParameterError(f"speed_mps must be > 0, got {speed_mps}", field="speed_mps")
    if not (0 < threshold < 1):
        raise ParameterError(f"threshold must be in (0, 1), got {threshold}", field="threshold")
    lam = np.geomspace(lambda_min_m, lambda_max_m, n)
    k = 2 * np.pi / lam
    H = vehicle_response(vehicle, k * speed_mps)
    # a measured point's level is the mean of its wheels' (a bogie averages its wheelbase out)
    front, rear = (
        np.mean([np.exp(1j * k * o) for o in offsets], axis=0)
        for offsets in vehicle.axle_wheel_offsets_m
    )
    u = np.stack([np.exp(1j * k * vehicle.d1) * front, np.exp(-1j * k * vehicle.d2) * rear], axis=1)
    resp = np.abs(np.einsum("wij,wj->wi", H, u))
    d1 = (lam >= 3.0) & (lam <= 25.0)
    ref = np.median(resp[d1], axis=0)
    ref[ref <= 0] = 1.0
    gain = np.sqrt(np.sum((resp / ref) ** 2, axis=1) / 2.0)
    low = gain < threshold
    ranges: list[tuple[float, float]] = []
    for a, b in true_runs(low):
        ranges.append((round(float(lam[a]), 2), round(float(lam[b - 1]), 2)))
    span = vehicle.d1 + vehicle.d2
    bounce = tuple(
        round(2 * span / (2 * j + 1), 2)
        for j in range(0, 100)
        if lambda_min_m <= 2 * span / (2 * j + 1) <= lambda_max_m
    )
    pitch = tuple(
        round(span / j, 2) for j in range(1, 100) if lambda_min_m <= span / j <= lambda_max_m
    )
    wheelbases = {
        round(max(o) - min(o), 6) for o in vehicle.axle_wheel_offsets_m if max(o) > min(o)
    }
    wheelbase = tuple(
        sorted(
            round(2 * a / (2 * j + 1), 2)
            for a in wheelbases
            for j in range(0, 100)
            if lambda_min_m <= 2 * a / (2 * j + 1) <= lambda_max_m
        )
    )
    return Observability(
        lam, gain, bounce, pitch, tuple(ranges), float(speed_mps), threshold, wheelbase
    )


# ------------------------------------------------------------------------ section statistics


@dataclass(frozen=True)
class SectionStat:
    """Standard deviation of the band-filtered level over one section.

    ``sd_mm`` maps band name to SD (mm, NaN where fewer than ``min_coverage`` of the section's
    points have a value); ``coverage`` is the share of the section's points with a D1 value.
    """

    start_m: float
    end_m: float
    sd_mm: dict[str, float]
    coverage: float


def section_bounds(
    start_m: float, end_m: float, section_m: float, origin_m: float = 0.0
) -> list[tuple[float, float]]:
    """Sections ``[origin + k L, origin + (k+1) L)`` overlapping ``[start_m, end_m]``, m."""
    if not (section_m > 0 and math.isfinite(section_m)):
        raise ParameterError(f"section_m must be > 0, got {section_m}", field="section_m")
    k0 = math.floor((start_m - origin_m) / section_m)
    k1 = math.ceil((end_m - origin_m) / section_m)
    return [
        (origin_m + k * section_m, origin_m + (k + 1) * section_m)
        for k in range(k0, max(k1, k0 + 1))
    ]


def section_statistics(
    chainage_m: ArrayLike,
    filtered_mm: dict[str, NDArray[np.float64]],
    section_m: float = 200.0,
    *,
    origin_m: float = 0.0,
    min_coverage: float = 0.5,
) -> list[SectionStat]:
    """SD of each band's filtered level per section (EN 13848-6: 200 m by default).

    Parameters
    ----------
    chainage_m : array_like
        Regular grid, m, increasing.
    filtered_mm : dict
        Band name -> filtered level on that grid, mm (NaN where unknown).
    section_m, origin_m : float
        Section length and the chainage sections are counted from, m.
    min_coverage : float
        Least share of a section's grid points with a value for its SD to be given (0-1].
    """
    x = np.asarray(chainage_m, dtype=np.float64)
    if x.size < 2:
        return []
    if not (0 < min_coverage <= 1):
        raise ParameterError(
            f"min_coverage must be in (0, 1], got {min_coverage}", field="min_coverage"
        )
    step = float(np.median(np.diff(x)))
    out = []
    for a, b in section_bounds(float(x[0]), float(x[-1]), section_m, origin_m):
        m = (x >= a - 1e-9) & (x < b - 1e-9)
        expected = max(1, int(round(section_m / step)))
        sd: dict[str, float] = {}
        cov = 0.0
        for name, v in filtered_mm.items():
            vals = np.asarray(v)[m]
            vals = vals[np.isfinite(vals)]
            share = vals.size / expected
            if name == "D1" or not sd:
                cov = share
            sd[name] = float(np.std(vals)) if share >= min_coverage and vals.size > 1 else math.nan
        out.append(SectionStat(a, b, sd, min(1.0, cov)))
    return out


# ------------------------------------------------------------------------------ repeatability


@dataclass(frozen=True)
class Repeatability:
    """95th percentile of ``|difference|`` between passes' filtered levels (mm), over
    ``n_points`` shared points of ``n_pairs`` pairs (EN 13848-2's 95 % criterion)."""

    r95_mm: float
    n_pairs: int
    n_points: int


def repeatability(
    passes: Sequence[NDArray[np.floating[Any]]], *, pairs: str = "all"
) -> Repeatability:
    """Repeatability of filtered levels on one grid (NaN where a pass has no value).

    ``pairs``: ``"all"`` pairs of passes, or ``"successive"`` (each pass with the next, the
    passes in recording order: linear in their number, for many passes).
    """
    if pairs not in ("all", "successive"):
        raise ParameterError(f"pairs must be 'all' or 'successive', got {pairs!r}", field="pairs")
    n = len(passes)
    chosen = (
        [(i, j) for i in range(n) for j in range(i + 1, n)]
        if pairs == "all"
        else [(i, i + 1) for i in range(n - 1)]
    )
    diffs = []
    used = 0
    for i, j in chosen:
        d = np.asarray(passes[i]) - np.asarray(passes[j])
        d = d[np.isfinite(d)]
        if d.size:
            diffs.append(np.abs(d))
            used += 1
    if not diffs:
        return Repeatability(math.nan, 0, 0)
    all_d = np.concatenate(diffs)
    return Repeatability(float(np.percentile(all_d, 95)), used, int(all_d.size))


# ---------------------------------------------------------------------------------- trends


@dataclass(frozen=True)
class Crossing:
    """When a trended value reaches ``limit`` (a straight line through the passes' values).

    ``date`` is the fit's crossing, ``earliest``/``latest`` the crossings of the slope's
    confidence band (``latest`` None when the band allows no growth); ``reached`` when the
    latest value is already at the limit; all None when the value does not grow.
    """

    limit: float
    slope_per_year: float | None
    date: datetime | None
    earliest: datetime | None
    latest: datetime | None
    reached: bool = False


def predict_crossing(
    times: Sequence[datetime],
    values: Sequence[float],
    limit: float,
    *,
    confidence: float = 0.95,
    horizon_days: float = 3650.0,
) -> Crossing:
    """Date a growing value reaches ``limit``, with the interval from its slope's uncertainty.

    Needs three passes at distinct times; values are magnitudes (mm) and grow towards
    ``limit``. Crossings beyond ``horizon_days`` from the last pass are None.
    """
    pts = [(t, float(v)) for t, v in zip(times, values, strict=True) if math.isfinite(v)]
    if not pts:
        return Crossing(limit, None, None, None, None)
    pts.sort()
    last_t, last_v = pts[-1]
    if last_v >= limit:
        return Crossing(limit, None, last_t, last_t, last_t, reached=True)
    t0 = pts[0][0]
    d = np.array([(t - t0).total_seconds() / 86400.0 for t, _ in pts])
    y = np.array([v for _, v in pts])
    if len(pts) < 3 or np.ptp(d) <= 0:
        return Crossing(limit, None, None, None, None)
    fit = sstats.linregress(d, y)
    q = float(sstats.t.ppf(0.5 + confidence / 2, len(pts) - 2))
    slope, se = float(fit.slope), float(fit.stderr)
    level_now = float(fit.intercept + slope * d[-1])

    def when(s: float) -> datetime | None:
        if s <= 0:
            return None
        days = (limit - level_now) / s
        if days > horizon_days:
            return None
        return last_t + timedelta(days=max(0.0, days))

    return Crossing(
        limit,
        slope * 365.25,
        when(slope),
        when(slope + q * se),
        when(slope - q * se),
    )
