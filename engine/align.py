"""Run-to-run alignment: the chainage offset that lines a profile up with a reference.

Logged start chainages are off by metres (odometer slip, GPS). Two passes over the same track
see the same loaded profile, so the offset is where their cross-correlation peaks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .errors import ParameterError


@dataclass(frozen=True)
class Alignment:
    """Result of aligning a profile to a reference.

    Attributes
    ----------
    offset_m : float
        Add this to the run's chainages to put them on the reference, m.
    correlation : float
        Normalised correlation of the two profiles at that offset (-1..1).
    overlap_m : float
        Length of track both profiles cover at that offset, m.
    ok : bool
        Whether the offset can be trusted (enough overlap, a clear correlation peak).
    reason : str
        Why not, when ``ok`` is false.
    z_score : float
        How far the correlation at that offset stands above what two unrelated profiles of
        the same roughness reach by chance over that overlap, in standard deviations
        (:func:`correlation_z`): the peak's significance, whatever the profiles' noise.
    """

    offset_m: float
    correlation: float
    overlap_m: float
    ok: bool
    reason: str = ""
    z_score: float = float("nan")


def _autocorrelation(x: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    """Normalised autocorrelation of a zero-mean series at lags ``1..max_lag``."""
    n = x.size
    den = float(np.dot(x, x))
    if den <= 0 or n < 2:
        return np.zeros(max_lag)
    m = min(max_lag, n - 1)
    out = np.zeros(max_lag)
    f = np.fft.rfft(x, 2 * n)
    ac = np.fft.irfft(f * np.conj(f))[1 : m + 1]
    out[:m] = ac / den
    return out


def correlation_z(x: NDArray[np.float64], y: NDArray[np.float64], max_lag: int = 200) -> float:
    """Significance of the normalised correlation of two equally long series, in standard
    deviations of its null distribution.

    Two unrelated series of ``n`` samples correlate by chance with a standard deviation of
    ``sqrt((1 + 2 sum_k rho_x(k) rho_y(k)) / n)`` (Bartlett), ``rho`` their own
    autocorrelations: smooth (band-limited) profiles have few independent samples ``n_eff``,
    so the same correlation means less on them. Returned as Fisher's ``atanh(r)
    sqrt(n_eff - 3)`` (equal to ``r / sd`` for weak correlations, and not capped near 1).
    Measured on the two series, nothing assumed of their noise.
    """
    ok = np.isfinite(x) & np.isfinite(y)
    xm, ym = x[ok] - x[ok].mean(), y[ok] - y[ok].mean()
    n = xm.size
    den = math.sqrt(float(np.dot(xm, xm)) * float(np.dot(ym, ym)))
    if n < 8 or den <= 0:
        return float("nan")
    r = float(np.dot(xm, ym)) / den
    k = min(max_lag, n // 4)
    var = (1.0 + 2.0 * float(np.dot(_autocorrelation(xm, k), _autocorrelation(ym, k)))) / n
    n_eff = 1.0 / max(var, 1.0 / n)
    # Fisher's transform: near |r| = 1 the plain r / sd saturates at sqrt(n_eff)
    return math.atanh(min(max(r, -0.999999), 0.999999)) * math.sqrt(max(n_eff - 3.0, 1.0))


#: How far in from a log's ends its level rings, m: the spectral inverse pads the signals, not
#: the level, so a pass's first and last tens of metres err by up to ~1 mm, differently for each
#: pass (docs/accuracy.md, "The 25-40 m error is the ends' ring"). Left out of the alignment's
#: cross-correlation, a pass whose log starts elsewhere is aligned within a few cm instead of
#: tenths of a metre ("Aligning passes without their ends").
END_RING_M = 20.0


def _without_ends(
    chainage: NDArray[np.float64], level: NDArray[np.float64], edge_m: float, min_m: float
) -> NDArray[np.float64]:
    """``level`` with NaN within ``edge_m`` of its known stretch's ends (m), unless less than
    ``min_m`` would be left."""
    level = np.asarray(level, dtype=np.float64)
    known = np.flatnonzero(np.isfinite(level))
    if edge_m <= 0 or known.size == 0:
        return level
    lo, hi = chainage[known[0]] + edge_m, chainage[known[-1]] - edge_m
    if hi - lo < min_m:
        return level
    return np.where((chainage >= lo) & (chainage <= hi), level, np.nan)


def _correlations(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    lags: NDArray[np.int_],
    step: float,
    min_overlap_m: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Normalised correlation of ``a`` with ``b`` shifted by each lag (samples; NaN where
    the overlap is shorter than ``min_overlap_m``) and each overlap, m."""
    n = a.size
    corr = np.full(lags.size, np.nan)
    over = np.zeros(lags.size)
    for j, lag in enumerate(lags):
        # b shifted by lag samples: b_shift[i] = b[i - lag]
        if lag >= 0:
            x, y = a[lag:], b[: n - lag]
        else:
            x, y = a[:lag], b[-lag:]
        m = np.isfinite(x) & np.isfinite(y)
        cnt = int(m.sum())
        over[j] = cnt * step
        if cnt * step < min_overlap_m:
            continue
        xm, ym = x[m] - x[m].mean(), y[m] - y[m].mean()
        den = np.sqrt(np.dot(xm, xm) * np.dot(ym, ym))
        corr[j] = np.dot(xm, ym) / den if den > 0 else np.nan
    return corr, over


def _vertex(corr: NDArray[np.float64], j: int) -> float:
    """Sub-sample position of the peak at ``j`` from the parabola through it and its
    neighbours, samples (0 at an edge or where the three do not bend down)."""
    if not (0 < j < corr.size - 1 and np.all(np.isfinite(corr[j - 1 : j + 2]))):
        return 0.0
    c0, c1, c2 = corr[j - 1], corr[j], corr[j + 1]
    den = c0 - 2 * c1 + c2
    return float(0.5 * (c0 - c2) / den) if den < 0 else 0.0


def _refined_on_slopes(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    lag: int,
    refine_m: float,
    step: float,
    min_overlap_m: float,
    fallback: float,
) -> float:
    """The shift (samples) where the slopes of ``a`` and ``b`` correlate best within
    ``refine_m`` of ``lag``; ``fallback`` when their peak lies on the search's edge.

    The levels' correlation peak is as broad as their longest waves, which carry most of
    their energy and the inversion's largest errors (the ends' ring, the long-wave drift of
    one vehicle's transfer): those pull it by up to a tenth of a metre, differently for each
    vehicle. The slopes weight every wavelength by its wavenumber squared, so the short
    waves, measured best, place the peak.
    """
    r = int(np.ceil(refine_m / step))
    lags = np.arange(lag - r, lag + r + 1)
    corr, _ = _correlations(np.diff(a), np.diff(b), lags, step, min_overlap_m)
    if not np.any(np.isfinite(corr)):
        return fallback
    j = int(np.nanargmax(corr))
    if j in (0, lags.size - 1):
        return fallback
    return float(lags[j]) + _vertex(corr, j)


def align_profiles(
    ref_chainage: NDArray[np.float64],
    ref_level: NDArray[np.float64],
    chainage: NDArray[np.float64],
    level: NDArray[np.float64],
    *,
    max_shift_m: float = 10.0,
    min_overlap_m: float = 60.0,
    min_correlation: float = 0.5,
    edge_m: float = 0.0,
    refine_m: float = 0.5,
) -> Alignment:
    """Chainage offset of a profile against a reference profile, by cross-correlation.

    Parameters
    ----------
    ref_chainage, ref_level : ndarray
        Reference profile on a regular grid, m and mm (NaN where unknown).
    chainage, level : ndarray
        Profile to align, on a regular grid of the same step, m and mm.
    max_shift_m : float
        Largest offset searched, m (either way).
    min_overlap_m : float
        Shortest common stretch accepted, m.
    min_correlation : float
        Smallest normalised correlation accepted at the best offset.
    edge_m : float
        Length left out of the comparison at each end of the profile's known stretch, m
        (:data:`END_RING_M` for a level from the inverse, whose ends ring); not when less than
        ``min_overlap_m`` would be left.
    refine_m : float
        The offset is then refined on the profiles' slopes within this distance of the
        levels' correlation peak, m (0: not refined). The levels' peak finds the offset and
        judges it (correlation, significance); the slopes place it to a few centimetres.

    Returns
    -------
    Alignment
        The offset to the nearest tenth of a grid step (parabolic peak refinement).
    """
    step = float(chainage[1] - chainage[0])
    ref_step = float(ref_chainage[1] - ref_chainage[0])
    if abs(step - ref_step) > 1e-9 * max(step, 1.0):
        raise ParameterError(f"profiles must share a grid step: {ref_step} m vs {step} m")
    if max_shift_m <= 0:
        raise ParameterError("max_shift_m must be > 0 m")
    if edge_m < 0:
        raise ParameterError("edge_m must be >= 0 m")
    level = _without_ends(chainage, level, edge_m, min_overlap_m)
    # put both on one grid: index = (chainage - origin) / step
    origin = min(ref_chainage[0], chainage[0]) - max_shift_m - step
    n = int(round((max(ref_chainage[-1], chainage[-1]) + max_shift_m - origin) / step)) + 2
    a = np.full(n, np.nan)
    b = np.full(n, np.nan)
    ia = np.rint((ref_chainage - origin) / step).astype(int)
    ib = np.rint((chainage - origin) / step).astype(int)
    a[ia] = ref_level
    b[ib] = level
    k = int(np.ceil(max_shift_m / step))
    lags = np.arange(-k, k + 1)
    corr, over = _correlations(a, b, lags, step, min_overlap_m)
    if not np.any(np.isfinite(corr)):
        return Alignment(0.0, float("nan"), float(over.max()), False,
                         f"overlap shorter than {min_overlap_m:g} m")  # fmt: skip
    j = int(np.nanargmax(corr))
    best = float(corr[j])
    shift = float(lags[j]) + _vertex(corr, j)
    if 0 < j < lags.size - 1 and refine_m > 0:
        shift = _refined_on_slopes(a, b, int(lags[j]), refine_m, step, min_overlap_m, shift)
    offset = shift * step
    best_lag = int(lags[j])
    if best_lag >= 0:
        z = correlation_z(a[best_lag:], b[: n - best_lag])
    else:
        z = correlation_z(a[:best_lag], b[-best_lag:])
    if j in (0, lags.size - 1):
        edge = f"best match at the edge of the +-{max_shift_m:g} m search"
        return Alignment(offset, best, float(over[j]), False, edge, z)
    if best < min_correlation:
        return Alignment(offset, best, float(over[j]), False,
                         f"correlation {best:.2f} below {min_correlation:g}", z)  # fmt: skip
    return Alignment(offset, best, float(over[j]), True, "", z)
