"""Soft-spot detection on a fused loaded profile: local dips against a robust baseline."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import median_filter, uniform_filter1d

from .errors import ParameterError
from .intervals import merge_intervals

MATCHED_WIDTHS_M = (4.0, 8.0)
"""Running-mean widths the detector also searches at by default, m (see
:attr:`DetectionConfig.matched_m`)."""


@dataclass(frozen=True)
class DetectionConfig:
    """Thresholds of the soft-spot detector.

    Parameters
    ----------
    baseline_window_m : float
        Length of the running median that gives the baseline, m; longer than the longest
        soft zone expected (a dip narrower than half of it does not move the median).
    min_depth_mm : float
        Smallest dip reported, mm below the baseline.
    noise_factor : float
        A dip must also be deeper than this many robust standard deviations of the residual.
    min_length_m : float
        Shortest dip reported (width at half depth), m.
    edge_m : float
        Dips closer than this to either end of the profile are ignored, m (filter edge effects).
    matched_m : tuple of float
        Widths of running means the residual is also searched at, m, each against the spread
        of the residual averaged the same way (``noise_factor`` of it). A long zone's dip is
        wider than the noise's correlation length, so the average keeps its depth and lowers
        the noise: a matched filter for a flat-bottomed dip. Dips found only at a width are
        added; empty: the residual alone.
    """

    baseline_window_m: float = 40.0
    min_depth_mm: float = 0.06
    noise_factor: float = 5.0
    min_length_m: float = 1.0
    edge_m: float = 6.0
    matched_m: tuple[float, ...] = MATCHED_WIDTHS_M

    def __post_init__(self) -> None:
        for name in ("baseline_window_m", "min_depth_mm", "noise_factor", "min_length_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ParameterError(f"detection {name} must be > 0, got {v}")
        if not (np.isfinite(self.edge_m) and self.edge_m >= 0):
            raise ParameterError(f"detection edge_m must be >= 0, got {self.edge_m}")
        for w in self.matched_m:
            if not (np.isfinite(w) and 0 < w < self.baseline_window_m):
                raise ParameterError(
                    f"detection matched_m widths must be > 0 m and shorter than the baseline "
                    f"window {self.baseline_window_m} m, got {w}",
                    field="matched_m",
                )


@dataclass(frozen=True)
class Dip:
    """A detected dip before stiffness fitting: its extent and depth.

    Every soft-spot record of the engine that reports a dip of the loaded level
    (:class:`engine.results.SoftSpot`, :class:`engine.accumulate.AggregateSpot`) is a ``Dip``
    with figures of its own after these.

    Attributes
    ----------
    start_m, end_m : float
        Chainage where the dip starts and ends, m.
    peak_m : float
        Chainage of the deepest point, m.
    depth_mm : float
        Depth below the local baseline, mm (positive = deeper).
    """

    start_m: float
    end_m: float
    peak_m: float
    depth_mm: float


def robust_baseline(
    level_mm: NDArray[np.float64], step_m: float, window_m: float
) -> NDArray[np.float64]:
    """Slowly varying baseline of a profile: running median then running mean, mm.

    NaN samples are filled from their neighbours for the computation and stay NaN.
    Computed on a grid decimated to about 0.5 m, so its cost stays small on long runs.
    """
    y = np.asarray(level_mm, dtype=float)
    ok = np.isfinite(y)
    out = np.full_like(y, np.nan)
    if ok.sum() < 2:
        return out
    idx = np.arange(y.size)
    filled = np.interp(idx, idx[ok], y[ok])
    dec = max(1, int(round(0.5 / step_m)))
    coarse = filled[::dec]
    size = max(3, int(round(window_m / (step_m * dec))) | 1)
    med = median_filter(coarse, size=size, mode="reflect")
    smooth = uniform_filter1d(med, size=max(1, size // 4), mode="reflect")
    base = np.interp(idx, idx[::dec], smooth)
    out[ok] = base[ok]
    return out


def robust_sigma(x: NDArray[np.float64]) -> float:
    """Standard deviation estimated from the median absolute deviation (NaN ignored)."""
    v = x[np.isfinite(x)]
    if v.size == 0:
        return 0.0
    return float(1.4826 * _median(np.abs(v - _median(v))))


def _median(v: NDArray[np.float64]) -> np.float64:
    """``np.median(v)`` of NaN-free values (at least one), the same number at a third of its
    time on a few thousand (one partition; of an even count the mean of the two middle
    values, the lower one the largest below the partition point, as numpy takes them)."""
    k = v.size // 2
    p = np.partition(v, k)
    if v.size % 2:
        return p[k]
    return (p[:k].max() + p[k]) / 2


def running_mean(x: NDArray[np.float64], step_m: float, width_m: float) -> NDArray[np.float64]:
    """Running mean of ``x`` over ``width_m`` (m) along its last axis, NaN ignored and kept.

    ``x`` is one profile (points,) or several (rows, points) on a grid of ``step_m`` (m).
    """
    n = max(1, int(round(width_m / step_m)))
    ok = np.isfinite(x)
    num = uniform_filter1d(np.where(ok, x, 0.0), n, axis=-1, mode="nearest")
    den = uniform_filter1d(ok.astype(float), n, axis=-1, mode="nearest")
    with np.errstate(invalid="ignore", divide="ignore"):
        out: NDArray[np.float64] = np.where(ok & (den > 0), num / den, np.nan)
    return out


def dip_thresholds(
    step_m: float, residual_mm: NDArray[np.float64], config: DetectionConfig
) -> tuple[tuple[float, float], ...]:
    """The detector's threshold at every width it searches: ``(width m, threshold mm)``, the
    residual itself first (width 0), then each of ``config.matched_m``."""
    out = [(0.0, max(config.min_depth_mm, config.noise_factor * robust_sigma(residual_mm)))]
    for w in config.matched_m:
        sm = running_mean(residual_mm, step_m, w)
        out.append((float(w), max(config.min_depth_mm, config.noise_factor * robust_sigma(sm))))
    return tuple(out)


def find_dips(
    chainage_m: NDArray[np.float64],
    residual_mm: NDArray[np.float64],
    config: DetectionConfig,
    *,
    thresholds: tuple[tuple[float, float], ...] | None = None,
) -> tuple[list[Dip], float]:
    """Dips of a residual profile (level minus baseline) below the detection threshold.

    Returns the dips ordered by chainage and the threshold of the residual itself, mm. A dip's
    extent is where the residual is below half its peak depth; dips at most ``min_length_m``
    apart merge (:func:`engine.intervals.merge_intervals`). The residual's running means of
    ``config.matched_m`` are searched the same way, each against its own threshold
    (:func:`dip_thresholds`); a dip found there and not in the residual is added, its extent
    the mean's half-depth extent, its depth the residual's deepest point inside it.
    ``thresholds``: :func:`dip_thresholds` of the residual, when already at hand.
    """
    step = float(chainage_m[1] - chainage_m[0])
    if thresholds is None:
        thresholds = dip_thresholds(step, residual_mm, config)
    dips = _dips_below(chainage_m, residual_mm, thresholds[0][1], config)
    for w, thr_w in thresholds[1:]:
        found = _dips_below(chainage_m, running_mean(residual_mm, step, w), thr_w, config)
        dips = add_dips(chainage_m, residual_mm, dips, found)
    return dips, thresholds[0][1]


def add_dips(
    chainage_m: NDArray[np.float64],
    residual_mm: NDArray[np.float64],
    dips: list[Dip],
    more: list[Dip],
) -> list[Dip]:
    """``dips`` and those of ``more`` that overlap none of them, by chainage.

    ``more`` are dips of a running mean of ``residual_mm`` (mm): each keeps its extent and
    takes its deepest point and depth from the residual itself inside it.
    """
    out = list(dips)
    for d in more:
        if any(d.start_m <= o.end_m and o.start_m <= d.end_m for o in dips):
            continue
        inside = (chainage_m >= d.start_m) & (chainage_m <= d.end_m) & np.isfinite(residual_mm)
        if not inside.any():
            out.append(d)
            continue
        k = int(np.argmin(np.where(inside, residual_mm, np.inf)))
        out.append(Dip(d.start_m, d.end_m, float(chainage_m[k]), float(-residual_mm[k])))
    out.sort(key=lambda d: d.start_m)
    return out


def _dips_below(
    chainage_m: NDArray[np.float64],
    residual_mm: NDArray[np.float64],
    thr: float,
    config: DetectionConfig,
) -> list[Dip]:
    """Dips of ``residual_mm`` deeper than ``thr`` (mm), grown to half depth and merged."""
    step = float(chainage_m[1] - chainage_m[0])
    r = np.where(np.isfinite(residual_mm), residual_mm, 0.0)
    valid = np.isfinite(residual_mm)
    idx = np.flatnonzero(valid)
    if idx.size == 0:
        return []
    lo_ok = chainage_m[idx[0]] + config.edge_m
    hi_ok = chainage_m[idx[-1]] - config.edge_m
    below = (r < -thr) & valid
    dips: list[Dip] = []
    taken = np.zeros(r.size, dtype=bool)
    # visit candidate minima from the deepest, growing each to its half-depth extent
    order = np.flatnonzero(below)
    order = order[np.argsort(r[order])]
    for k in order:
        if taken[k]:
            continue
        half = 0.5 * r[k]
        a = k
        while a > 0 and r[a - 1] < half and valid[a - 1]:
            a -= 1
        b = k
        while b < r.size - 1 and r[b + 1] < half and valid[b + 1]:
            b += 1
        taken[max(0, a - 1) : b + 2] = True
        # linear interpolation of the half-depth crossings
        xa = chainage_m[a]
        if a > 0 and r[a - 1] != r[a]:
            xa -= step * (half - r[a]) / (r[a - 1] - r[a])
        xb = chainage_m[b]
        if b < r.size - 1 and r[b + 1] != r[b]:
            xb += step * (half - r[b]) / (r[b + 1] - r[b])
        if xb - xa < config.min_length_m:
            continue
        if chainage_m[k] < lo_ok or chainage_m[k] > hi_ok:
            continue
        dips.append(Dip(float(xa), float(xb), float(chainage_m[k]), float(-r[k])))
    merged: list[Dip] = []
    for group in merge_intervals(
        [d.start_m for d in dips], [d.end_m for d in dips], config.min_length_m
    ):
        members = [dips[i] for i in group]
        deepest = max(members, key=lambda d: d.depth_mm)
        end = max(d.end_m for d in members)
        merged.append(Dip(members[0].start_m, end, deepest.peak_m, deepest.depth_mm))
    return merged
