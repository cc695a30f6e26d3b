"""Many passes of one track combined: alignment against the many-pass estimate, the measured
noise of the combination and soft-spot detection on it.

One MEMS pass sees little (its own noise hides all but the deepest zones) and aligns badly
against another noisy pass, but N passes averaged see what one good sensor sees. So no pass is
dropped: a pass whose offset cannot be trusted joins at its logged chainage (an error of a
metre or so blurs a zone's edges, it does not hide it), every pass is then aligned again
against the weighted mean of all the *others* (whose noise falls as passes come), and the mean
is detected with a threshold from its own measured noise.

The noise of the mean is measured, not assumed to fall as 1/sqrt(N): the passes are split in
two halves of equal weight and the difference of the halves' means, scaled to the full set,
holds the noise of the mean and none of the track's signal (common to both). Whatever the
passes share (the same vehicle dynamics on the same rail) cancels there as in the signal;
what they do not (sensor noise, bias wander, alignment errors along the track) is measured.

Units: chainage in m, levels in mm (band-passed loaded level, positive up), loads in N.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from .aggregate import column_median_spread, column_nanmedian
from .align import Alignment, align_profiles
from .chainage import PRODUCT_BAND_M, to_grid
from .detect import (
    DetectionConfig,
    Dip,
    add_dips,
    find_dips,
    robust_baseline,
    robust_sigma,
    running_mean,
)
from .errors import ParameterError
from .geometry_check import is_smooth_rail
from .kept import KeptArrays
from .track import TrackParams

MIN_Z = 8.0
"""Smallest correlation significance (:func:`engine.align.correlation_z`) at which a pass's
offset against the others' mean is trusted. Below it the pass stays at its logged chainage.
Industrial-MEMS passes reach 5.5-7 against one other pass and well above 10 against a mean of
four; 8 keeps chance peaks (a support-spacing alias) out."""


COMBINED_NOISE_FACTOR = 4.5
"""Depth a dip of the combined passes needs, in units of sqrt(noise² + roughness²) at its place
(one pass's detector uses 5 of its residual's whole spread). Measured on development tracks
(seeds 11-14 of ``benchmarks/accuracy_passes.py``, 4-16 passes of three grades): 4.5 finds
16/16 zones with industrial passes where 5 finds 15/16, with no false zone in 36 combinations;
4.0 gives a false zone with fibre-optic passes."""

SHORT_BASELINE_M = 30.0
"""Baseline window of the combination's second look, m: three times the longest zone (10 m)
a design track holds, so a zone's dip is at most a third of the window and the running
median stays on the rail beside it."""

FIT_GAP_M = 40.0
"""Gap between chains of dips, m, that their stiffness fits do not bridge: a fit keeps a zone
within seven support spacings (4-5 m) of the extent it starts from, and only zones whose
fitted extents overlap merge (and are fitted again), so only some nine merges in a row could
reach across. A detection that wants the spots of one stretch only (``peaks_in_m``) fits the
chains of dips at most this far apart that hold a dip whose deepest point lies there."""


@dataclass(frozen=True)
class PassPlacement:
    """Where one pass sits on the combined chainage.

    Attributes
    ----------
    offset_m : float
        Added to the pass's logged chainage, m.
    aligned : bool
        Whether the offset was found by correlation (else the pass is placed at its logged
        chainage, recentred with the others, and its position is as uncertain as that).
    z_score : float
        Significance of its last correlation against the others' mean (NaN: none tried).
    """

    offset_m: float
    aligned: bool
    z_score: float


def pass_noise(
    levels_mm: NDArray[np.float64],
    step_m: float,
    window_m: float,
    *,
    res: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Each pass's measured noise, mm: the robust spread of its residual (level minus its
    baseline) around the median residual of all passes. With one pass, the spread of its own
    residual (signal included: nothing else to compare with).

    Parameters
    ----------
    levels_mm : ndarray, shape (passes, points)
        Levels on one grid, NaN where a pass does not cover.
    step_m : float
        Grid step, m.
    window_m : float
        Baseline window, m (as the detector's).
    res : ndarray, optional
        The levels' :func:`residuals` when already at hand (the running medians are most of
        the cost).
    """
    res = residuals(levels_mm, step_m, window_m) if res is None else res
    if res.shape[0] == 1:
        return np.array([max(robust_sigma(res[0]), 1e-6)])
    fin = np.isfinite(res)
    n = fin.sum(axis=0)
    has = n > 0
    med = np.full(res.shape[1], np.nan)
    # (every column covered, as mostly: no copy of the covered columns)
    med[has] = column_nanmedian(res, n) if has.all() else column_nanmedian(res[:, has], n[has])
    use = fin & (n >= 2)
    count = use.sum(axis=1)
    # the median includes the pass itself: its deviation from it is (N-1)/N of its noise
    nn = np.where(count > 0, (n * use).sum(axis=1) / np.maximum(count, 1), 1.0)
    out = np.full(res.shape[0], np.nan)
    measured = count >= 20
    if measured.any():
        # every pass's robust_sigma of its deviations at once: one column per pass
        d = np.where(use, res - med, np.nan)[measured].T
        _, spread = column_median_spread(d, np.isfinite(d).sum(axis=0))
        out[measured] = spread * nn[measured] / np.maximum(nn[measured] - 1.0, 1.0)
    good = np.isfinite(out) & (out > 0)
    if good.all():
        return np.maximum(out, 1e-6)
    fallback = np.nanmedian(out) if np.isfinite(out).any() else 1.0
    # identical passes (no noise to measure) still weigh finitely: the one-pass floor
    return np.maximum(np.where(good, out, fallback), 1e-6)


def residuals(
    levels_mm: NDArray[np.float64],
    step_m: float,
    window_m: float,
    *,
    cache: ResidualCache | None = None,
) -> NDArray[np.float64]:
    """Each pass's level minus its own running baseline (:func:`engine.detect.robust_baseline`);
    with ``cache``, a row met before is not filtered again."""
    lv = np.atleast_2d(np.asarray(levels_mm, dtype=np.float64))
    if cache is not None:
        return np.stack([cache.residual(row, step_m, window_m) for row in lv])
    return np.stack([row - robust_baseline(row, step_m, window_m) for row in lv])


class ResidualCache(KeptArrays):
    """The residuals (:func:`residuals`) of the passes' level rows seen last, by content.

    A track's combined detection runs again on every pass that arrives, over the same
    stretch, with every earlier pass's row unchanged: their running medians (most of the
    detection's cost besides the fits) are taken from here. A row is known by a digest of
    its bytes, grid step and window, so a changed row (a pass moved, the stretch grown) is
    filtered again and the residuals are the same numbers either way. Thread-safe; the
    least recently used rows go first once the rows kept exceed ``max_bytes``.

    Parameters
    ----------
    max_bytes : int
        Memory the kept rows may take, bytes. The default, 64 MiB, keeps some 1300 rows of
        a 1.5 km detection stretch on the 0.25 m grid (48 kB each): a 20 km run's 20 units
        of 50 passes each, so a run over a long line finds its earlier units' rows.
    """

    def __init__(self, max_bytes: int = 64 * 2**20) -> None:
        super().__init__(max_bytes)

    def residual(
        self, row: NDArray[np.float64], step_m: float, window_m: float
    ) -> NDArray[np.float64]:
        """``row`` minus its running baseline, mm (a copy: the kept one stays as it is)."""
        row = np.ascontiguousarray(row, dtype=np.float64)
        # SHA-256 runs on the CPU's SHA extensions where it has them (x86 since ~2017,
        # ARMv8): half blake2b's time on a 48 kB row here; hashed in place, not copied
        h = hashlib.sha256(row.data.cast("B"))
        h.update(np.array([step_m, window_m, row.size], dtype=np.float64).tobytes())
        key = h.digest()
        got = self.get(key)
        if got is not None:
            return got.copy()
        out = row - robust_baseline(row, step_m, window_m)
        if out.nbytes <= self.max_bytes:
            self.put(key, out.copy(), out.nbytes)
        return out


def weighted_mean(
    values: NDArray[np.float64], weights: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per point, the weighted mean of the finite values of ``values`` (passes x points) with
    per-pass ``weights``, and the sum of the weights there (0 and NaN where none covers)."""
    ok = np.isfinite(values)
    w = _weights_at(ok, weights)
    sw = w.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(sw > 0, (w * np.where(ok, values, 0.0)).sum(axis=0) / sw, np.nan)
    return mean, sw


def _weights_at(ok: NDArray[np.bool_], weights: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each pass's weight where its value is finite (``ok``, passes x points), else 0."""
    return np.where(ok, weights[:, None], 0.0)


@dataclass(frozen=True)
class CombinedNoise:
    """The measured noise of a weighted mean of passes.

    Attributes
    ----------
    noise_mm : ndarray
        Standard deviation of the mean's error per point, mm (from the weights there).
    scale : float
        Measured noise of the mean over what the passes' own noise figures predict if their
        errors were independent (1: they are; > 1: they share part of their errors).
    halves : bool
        Whether the noise was measured by split halves (False with one pass: the pass's own
        spread is used).
    roughness_mm : float
        Spread of what the two halves share, mm: the rail's own level (support scatter,
        geometry) and the method's errors common to every pass, from the robust covariance
        of the halves' means (noise does not correlate between them). 0 with one pass.
    """

    noise_mm: NDArray[np.float64]
    scale: float
    halves: bool
    roughness_mm: float = 0.0


def combined_noise(res: NDArray[np.float64], sigma: NDArray[np.float64]) -> CombinedNoise:
    """Measured noise of the inverse-variance weighted mean of the residuals ``res``
    (passes x points, mm) of passes with noise ``sigma`` (mm).

    The passes, in the order given (recording order), are cut into an earlier and a later
    half of about equal weight; per point the difference of the halves' means times
    ``sqrt(W1 W2) / (W1 + W2)`` (``W`` the sums of weights there) has the variance of the
    full mean's error if the weights are right and the passes' errors independent, and
    ``scale`` corrects that by its measured spread. Passes close in time that share an error
    (one vehicle's campaign, one season) stay on one side, so the error they share is
    measured too and the noise falls more slowly than ``1/sqrt(N)``, as it does. An error
    common to every pass cannot be told from the track by any split.
    """
    w = 1.0 / sigma**2
    sw = _weights_at(np.isfinite(res), w).sum(axis=0)  # weighted_mean's, without the mean
    if res.shape[0] < 2:
        with np.errstate(divide="ignore"):
            noise = np.where(sw > 0, sigma[0] * np.ones(res.shape[1]), np.nan)
        return CombinedNoise(noise, 1.0, False)
    cum = np.cumsum(w)
    half = cum - 0.5 * w <= 0.5 * cum[-1]
    if half.all() or not half.any():
        half = np.arange(res.shape[0]) < res.shape[0] // 2 + (res.shape[0] % 2)
    m1, w1 = weighted_mean(res[half], w[half])
    m2, w2 = weighted_mean(res[~half], w[~half])
    both = (w1 > 0) & (w2 > 0)
    scale, rough = 1.0, 0.0
    if both.sum() >= 40:
        with np.errstate(invalid="ignore", divide="ignore"):
            u = (m1 - m2) * np.sqrt(w1 * w2) / (w1 + w2) * np.sqrt(w1 + w2)
        scale = robust_sigma(u[both])
        # 4 cov(m1, m2) = var(m1 + m2) - var(m1 - m2), each spread robust to the zones
        cov4 = robust_sigma((m1 + m2)[both]) ** 2 - robust_sigma((m1 - m2)[both]) ** 2
        rough = math.sqrt(max(cov4, 0.0) / 4.0)
    with np.errstate(divide="ignore"):
        noise = np.where(sw > 0, scale / np.sqrt(sw), np.nan)
    return CombinedNoise(noise, float(scale), True, rough)


@dataclass(frozen=True)
class AggregateSpot(Dip):
    """A soft spot of the combined passes.

    The extent, deepest point and depth (of the combined level below its baseline) are
    :class:`engine.detect.Dip`'s.

    Attributes
    ----------
    stiffness_loss_pct : float
        Fitted stiffness loss, % (NaN where the combined level is not smooth rail or no load
        was given).
    significance : float
        Depth over the combined level's measured noise there.
    supporting : tuple of int
        Passes (row indices) that cover the spot and dip there themselves (their mean
        residual over the extent at least half the combined one).
    covering : tuple of int
        Passes that cover the whole spot.
    """

    stiffness_loss_pct: float
    significance: float
    supporting: tuple[int, ...]
    covering: tuple[int, ...]


@dataclass(frozen=True)
class AggregateDetection:
    """Soft-spot detection on the weighted mean of passes.

    Attributes
    ----------
    chainage_m : ndarray
        Grid, m.
    residual_mm : ndarray
        Weighted mean of the passes' residuals, mm.
    noise : CombinedNoise
        Its measured noise.
    threshold_mm : ndarray
        Depth a dip needs per point, mm.
    pass_noise_mm : ndarray
        Each pass's measured noise, mm.
    roughness_mm : float
        Spread of what every pass shares (:attr:`CombinedNoise.roughness_mm`), mm.
    smooth : bool
        Whether that roughness is smooth rail (losses fitted) or not.
    spots : list of AggregateSpot
        What was found, by chainage.
    """

    chainage_m: NDArray[np.float64]
    residual_mm: NDArray[np.float64]
    noise: CombinedNoise
    threshold_mm: NDArray[np.float64]
    pass_noise_mm: NDArray[np.float64]
    roughness_mm: float
    smooth: bool
    spots: list[AggregateSpot]


def detect_on_aggregate(
    chainage_m: NDArray[np.float64],
    levels_mm: NDArray[np.float64],
    *,
    load_n: float | None = None,
    track: TrackParams | None = None,
    config: DetectionConfig | None = None,
    lambda_min_m: float = PRODUCT_BAND_M[0],
    lambda_max_m: float = PRODUCT_BAND_M[1],
    peaks_in_m: tuple[float, float] | None = None,
    cache: ResidualCache | None = None,
) -> AggregateDetection:
    """Soft spots of many aligned passes, against the measured noise of their combination.

    Parameters
    ----------
    chainage_m : ndarray, shape (g,)
        Regular grid, m.
    levels_mm : ndarray, shape (passes, g)
        Each pass's loaded level on the grid (band-passed, as processed), mm; NaN where it
        does not cover.
    load_n : float, optional
        Static wheel load the levels correspond to (the passes' mean), N; without it no
        stiffness loss is fitted.
    track : TrackParams, optional
        Nominal rail and supports (for the loss fit).
    config : DetectionConfig, optional
        Detector settings: a dip needs ``noise_factor`` (default
        :data:`COMBINED_NOISE_FACTOR` for two passes or more, one pass's 5 for one) times
        the combined level's measured noise at its place and the rail's own roughness (root
        sum of squares), and at least ``min_depth_mm``.
    lambda_min_m, lambda_max_m : float
        Band of the levels, m.
    peaks_in_m : (float, float), optional
        Only the spots whose deepest point lies in ``[lo, hi)`` m are wanted (the rest of the
        levels are context): the others are not returned, and dips further than
        :data:`FIT_GAP_M` from them (chain-wise) are not fitted. The spots returned are
        those a detection without it finds there.
    cache : ResidualCache, optional
        Where the passes' residuals are kept between detections.

    Returns
    -------
    AggregateDetection
    """
    cfg = config or DetectionConfig()
    grid = np.asarray(chainage_m, dtype=np.float64)
    lv = np.atleast_2d(np.asarray(levels_mm, dtype=np.float64))
    if grid.ndim != 1 or grid.size < 2 or lv.shape[1] != grid.size:
        raise ParameterError(
            "levels_mm must be (passes, points) on chainage_m, a grid of >= 2 points",
            field="levels_mm",
        )
    if load_n is not None and not (math.isfinite(load_n) and load_n > 0):
        raise ParameterError("load_n must be a positive wheel load, N", field="load_n")
    step = float(grid[1] - grid[0])
    if peaks_in_m is not None and not peaks_in_m[0] < peaks_in_m[1]:
        raise ParameterError("peaks_in_m must be (lo, hi) with lo < hi, m", field="peaks_in_m")
    res = residuals(lv, step, cfg.baseline_window_m, cache=cache)
    sigma = pass_noise(lv, step, cfg.baseline_window_m, res=res)
    mean, _ = weighted_mean(res, 1.0 / sigma**2)
    if config is None and res.shape[0] >= 2:
        # one pass has nothing to measure its noise against: the single-pass detector's 5
        cfg = replace(cfg, noise_factor=COMBINED_NOISE_FACTOR)
    # the dip is searched in several looks, each against the noise and roughness measured
    # the same way (split halves) on the passes' residuals of that look: the detector's
    # running means (a matched filter for wide dips), and the residuals against a shorter
    # baseline, which leaves a zone's dip whole and removes the long-wave error that
    # dominates the mean of noisy passes (one pass: the single-pass detector's looks)
    looks = [(res, sigma, mean)]
    if res.shape[0] >= 2:
        short = residuals(lv, step, SHORT_BASELINE_M, cache=cache)
        sigma_s = pass_noise(lv, step, SHORT_BASELINE_M, res=short)
        looks.append((short, sigma_s, weighted_mean(short, 1.0 / sigma_s**2)[0]))
    for r, _, m in list(looks):
        for w in cfg.matched_m:
            r_w = running_mean(r, step, w)
            sigma_w = pass_noise(lv, step, cfg.baseline_window_m, res=r_w)
            looks.append((r_w, sigma_w, running_mean(m, step, w)))
    noise, thr, dips = _dips_in_looks(grid, mean, looks, cfg)
    roughness = noise.roughness_mm
    if peaks_in_m is not None:
        dips = dips_near(dips, *peaks_in_m)
    # a noisy mean of smooth rail is smooth rail: the roughness decides
    smooth = bool(is_smooth_rail(roughness).smooth)
    fitted: list[tuple[float, float, float, float]] = []
    if dips and smooth and load_n is not None:
        # the single-pass fit and merge of overlapping zones, on the combined residual
        from .pipeline import ProcessConfig, _soft_spots

        pcfg = ProcessConfig(lambda_min_m=lambda_min_m, lambda_max_m=lambda_max_m, detection=cfg)
        for s in _soft_spots(grid, mean, dips, pcfg, track or TrackParams(), load_n):
            fitted.append((s.start_m, s.end_m, s.peak_m, s.stiffness_loss_pct))
    else:
        fitted = [(d.start_m, d.end_m, d.peak_m, float("nan")) for d in dips]
    if peaks_in_m is not None:
        fitted = [f for f in fitted if peaks_in_m[0] <= f[2] < peaks_in_m[1]]
    spots = []
    for a, b, peak, loss in fitted:
        inside = (grid >= a) & (grid <= b)
        if not inside.any():
            inside = np.abs(grid - peak) <= step
        k = int(np.argmin(np.abs(grid - peak)))
        depth = float(-mean[k]) if np.isfinite(mean[k]) else float("nan")
        nk = float(noise.noise_mm[k])
        # passes that agree exactly (the same log twice) leave no noise: infinitely significant
        sig = math.nan if not math.isfinite(nk) else depth / nk if nk > 0 else math.inf
        cover = np.flatnonzero(np.isfinite(res[:, inside]).all(axis=1))
        covering = tuple(int(j) for j in cover)
        m_all = float(np.nanmean(mean[inside]))
        # the covering passes are finite over the extent: their plain means, row by row
        own = res[np.ix_(cover, np.flatnonzero(inside))].mean(axis=1)
        supporting = tuple(int(j) for j, m in zip(cover, own, strict=True) if m <= 0.5 * m_all)
        spots.append(AggregateSpot(a, b, peak, depth, loss, sig, supporting, covering))
    return AggregateDetection(grid, mean, noise, thr, sigma, roughness, smooth, spots)


def _dips_in_looks(
    grid: NDArray[np.float64],
    mean: NDArray[np.float64],
    looks: list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]],
    cfg: DetectionConfig,
) -> tuple[CombinedNoise, NDArray[np.float64], list[Dip]]:
    """The dips of the combination ``mean`` (mm) found in any of its ``looks`` (each: the
    passes' residuals of the look, their noise and the look's weighted mean), each look
    against its own measured noise; with the first look's noise and threshold per point
    (mm)."""
    # the detector's own threshold is one number: scaling the residual by min_depth / thr(x)
    # makes "below -min_depth" mean "below -thr(x)" at every point
    flat = DetectionConfig(
        baseline_window_m=cfg.baseline_window_m, min_depth_mm=cfg.min_depth_mm,
        noise_factor=1e-12, min_length_m=cfg.min_length_m, edge_m=cfg.edge_m, matched_m=(),
    )  # fmt: skip
    out: tuple[CombinedNoise, NDArray[np.float64]] | None = None
    dips: list[Dip] = []
    for res_l, sigma_l, mean_l in looks:
        noise = combined_noise(res_l, sigma_l)
        # a dip must stand out of the noise and of the rail's own roughness (what every
        # pass shares), as a single pass's dip must stand out of its residual's whole
        # spread: the noise falls with passes, the roughness stays
        thr = np.maximum(
            cfg.min_depth_mm,
            cfg.noise_factor * np.sqrt(noise.noise_mm**2 + noise.roughness_mm**2),
        )
        with np.errstate(invalid="ignore"):
            found, _ = find_dips(grid, mean_l * (cfg.min_depth_mm / thr), flat)
        dips = add_dips(grid, mean, dips, found) if out else found
        out = out or (noise, thr)
    assert out is not None
    return out[0], out[1], dips


def dips_near(dips: list[Dip], lo_m: float, hi_m: float, gap_m: float = FIT_GAP_M) -> list[Dip]:
    """The dips (by chainage) of every chain of dips at most ``gap_m`` apart that holds a
    dip whose deepest point lies in ``[lo_m, hi_m)``: what the spots there can be fitted
    and merged from."""
    chains: list[list[Dip]] = []
    reach = -math.inf
    for d in sorted(dips, key=lambda d: d.start_m):
        if not chains or d.start_m - reach > gap_m:
            chains.append([])
        chains[-1].append(d)
        reach = max(reach, d.end_m)
    return [d for c in chains if any(lo_m <= x.peak_m < hi_m for x in c) for d in c]


def align_to_others(
    grid: NDArray[np.float64],
    levels_mm: NDArray[np.float64],
    weights: NDArray[np.float64],
    j: int,
    *,
    max_shift_m: float = 10.0,
    min_z: float = MIN_Z,
) -> tuple[float, float, bool]:
    """Offset of pass ``j`` against the weighted mean of the other passes (levels on
    ``grid``, passes x points, mm), the correlation's significance and whether the offset is
    trusted (:func:`trusted`; offset 0 when not)."""
    others = np.ones(levels_mm.shape[0], dtype=bool)
    others[j] = False
    ref, _ = weighted_mean(levels_mm[others], weights[others])
    own = levels_mm[j]
    if np.isfinite(ref).sum() < 8 or np.isfinite(own).sum() < 8:
        return 0.0, float("nan"), False
    al = align_profiles(grid, ref, grid, own, max_shift_m=max_shift_m)
    if not trusted(al, min_z=min_z):
        return 0.0, float(al.z_score), False
    return float(al.offset_m), float(al.z_score), True


def trusted(al: Alignment, *, min_z: float = MIN_Z, min_overlap_m: float = 60.0) -> bool:
    """Whether an offset found by :func:`engine.align.align_profiles` can be used: a clear
    correlation (``al.ok``), or a peak inside the search (not at its edge, over at least
    ``min_overlap_m``) significant at ``min_z``."""
    if al.ok:
        return True
    inside = "edge" not in al.reason and al.overlap_m >= min_overlap_m
    return inside and math.isfinite(al.z_score) and al.z_score >= min_z


def accumulate(
    chainages_m: Sequence[NDArray[np.float64]],
    levels_mm: Sequence[NDArray[np.float64]],
    *,
    step_m: float = 0.25,
    max_shift_m: float = 10.0,
    min_z: float = MIN_Z,
    rounds: int = 3,
    window_m: float = 40.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64], list[PassPlacement]]:
    """Put passes on one chainage, none dropped: each joins at its logged chainage and is
    then aligned against the noise-weighted mean of all the others, ``rounds`` times (each
    round's better mean aligns better). The frame is recentred so that the offsets average
    zero (each logged start is an unbiased estimate of the true one).

    Parameters
    ----------
    chainages_m, levels_mm : sequences of ndarray
        Each pass's regular chainage grid (m, step ``step_m``; increasing or decreasing, as
        the run was driven) and level (mm).
    step_m : float
        Grid step, m.
    max_shift_m : float
        Largest offset searched either way, m.
    min_z : float
        Smallest significance of a trusted offset.
    rounds : int
        Alignment rounds.
    window_m : float
        Baseline window of the noise measure, m.

    Returns
    -------
    grid, levels, placements
        Common grid (m), the passes' levels on it after their offsets (passes x points, mm)
        and where each pass went.
    """
    if len(chainages_m) != len(levels_mm) or not chainages_m:
        raise ParameterError("accumulate needs one level per chainage and at least one pass")
    lo = min(float(np.nanmin(c)) for c in chainages_m) - max_shift_m
    hi = max(float(np.nanmax(c)) for c in chainages_m) + max_shift_m
    grid = np.arange(math.floor(lo / step_m) * step_m, hi + 1e-9, step_m)
    n = len(chainages_m)
    offsets = np.zeros(n)
    aligned = np.zeros(n, dtype=bool)
    zs = np.full(n, np.nan)

    def place() -> NDArray[np.float64]:
        out = np.full((n, grid.size), np.nan)
        for j in range(n):
            c = np.asarray(chainages_m[j], dtype=np.float64) + offsets[j]
            out[j] = to_grid(c, np.asarray(levels_mm[j], dtype=np.float64), grid)
        return out

    levels = place()
    if n == 1:
        return grid, levels, [PassPlacement(0.0, False, float("nan"))]
    for _ in range(max(1, rounds)):
        w = 1.0 / pass_noise(levels, step_m, window_m) ** 2
        new = offsets.copy()
        for j in range(n):
            off, z, ok = align_to_others(grid, levels, w, j, max_shift_m=max_shift_m, min_z=min_z)
            zs[j] = z
            aligned[j] = ok
            new[j] = offsets[j] + off
        # the frame: the logged starts' mean is the best estimate of the true one
        new -= new.mean()
        if np.allclose(new, offsets, atol=0.01):
            offsets = new
            break
        offsets = new
        levels = place()
    levels = place()
    return (
        grid,
        levels,
        [
            PassPlacement(float(o), bool(a), float(z))
            for o, a, z in zip(offsets, aligned, zs, strict=True)
        ],
    )
