"""Placing a run on a centerline: its fixes projected onto the line, the odometer fitted to them.

The model (docs/method.md, "Positions from GNSS"): the body-centre chainage at time t is

    c(t) = c0 + k * odo(t) + sum_j dk_j * max(0, odo(t) - b_j)

with ``odo`` the distance the odometer (integrated speed, or the odometer column) says the
vehicle has travelled, ``sign(k)`` the direction of travel and ``|k|`` the odometer's scale
factor (wheel wear: 0.5-1 %). Knots ``b_j`` (a piecewise-linear, continuous fit) are added only
where the residuals show a trend the straight line cannot follow, judged with the residuals'
effective number of independent samples (GNSS errors wander: neighbouring fixes are not
independent). The fit is robust: a RANSAC start over pairs of fixes, then iteratively
reweighted least squares with Huber weights; fixes farther than ``max_offset_m`` from the line
are not used.

The fixes are thinned to :data:`FIX_INTERVAL_S` (and at most :data:`MAX_FIXES`) before they are
projected, so the work is bounded whatever the log's row rate: see :func:`thin_fixes` for why
the fit loses nothing by it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..budget import TimeBudget
from .centerline import Centerline
from .errors import FixesBesideLine, FixesDoNotFollowLine, FixesOffLine, NoFixes, TooFewFixes

MAX_OFFSET_M = 10.0
"""Farthest a fix may lie from the centerline and still be used, m: single fixes of a run on
the line stray this far (1-3 m GNSS error with a wandering bias, multipath outliers); whether
the run as a whole is on this track is :data:`LATERAL_TOLERANCE_M`'s question."""

LATERAL_TOLERANCE_M = 3.0
"""Largest steady sideways offset of a run from the centerline, m: the median signed lateral
offset of the fixes the fit used. Beyond it the run is refused as being on another track:
neighbouring track centres are 3.4-5 m apart (4.0-4.5 m on most main lines), while a run on
its own track is off by its GNSS bias (1-2 m for code GNSS; a short run sees one value of it)
plus how far the centerline is drawn from the track's middle (it should be within a metre: a
line drawn midway between two tracks, ~2 m from each, leaves little room for the bias)."""

FIX_INTERVAL_S = 0.1
"""Shortest time between two fixes the fit uses, s (10 Hz): see :func:`thin_fixes`."""

MAX_FIXES = 40_000
"""Most fixes one fit uses (an hour at 10 Hz fits): longer runs are thinned further."""

MIN_FIXES = 10
"""Fewest fixes near the line a placement needs."""

MIN_INLIER_FRACTION = 0.5
"""Least share of the near fixes the fitted line must explain (within :data:`INLIER_M`)."""

INLIER_M = 5.0
"""Residual within which a fix counts as following the fitted chainage, m."""

SCALE_RANGE = (0.85, 1.15)
"""Odometer scale factors accepted: a wheel worn or a speed signal off by up to 15 %."""

MIN_PIECE_M = 2000.0
"""Shortest stretch of odometer distance one piece of a piecewise fit may cover, m."""

MIN_SCALE_CHANGE = 0.002
"""Smallest change of odometer scale a knot may add (0.2 %, 2 m per km): smaller ones are
within what the GNSS bias's wander fakes over a few kilometres."""

MAX_KNOTS = 32
"""Most slope changes one run's fit may have."""

_HUBER_K = 1.345  # 95 % efficiency under Gaussian noise


@dataclass(frozen=True)
class Placement:
    """Where a run lies on a centerline, and how well its fixes say so.

    Attributes
    ----------
    c0_m : float
        Chainage at odometer distance 0 (the first sample), m.
    slope : float
        ``dc/d(odo)`` of the first piece: the direction (sign) times the odometer scale.
    knots_m : tuple of float
        Odometer distances where the slope changes, m (empty for one straight fit).
    slope_changes : tuple of float
        Change of slope at each knot.
    direction : str
        ``'increasing'`` or ``'decreasing'`` chainage.
    scale : float
        Odometer scale factor found (true distance / odometer distance), distance-weighted mean
        over the pieces.
    residual_rms_m : float
        RMS of the residuals of the fixes used, m.
    n_fixes : int
        Fixes in the log.
    n_considered : int
        Fixes left after thinning to :data:`FIX_INTERVAL_S` (:func:`thin_fixes`): those
        projected onto the line.
    n_used : int
        Fixes the fit used (near the line and following it).
    n_rejected : int
        ``n_considered - n_used``: off the line or outliers of the fit.
    offset_median_m, offset_p95_m : float
        Median and 95th percentile of the lateral offset (distance) of the fixes used, m.
    lateral_offset_m : float
        Median signed lateral offset of the fixes used, m: positive left of the line, negative
        right of it, looking towards increasing chainage (a steady offset: another track).
    odo_span_m : tuple of float
        First and last odometer distance of the run, m.
    """

    c0_m: float
    slope: float
    knots_m: tuple[float, ...]
    slope_changes: tuple[float, ...]
    direction: str
    scale: float
    residual_rms_m: float
    n_fixes: int
    n_used: int
    n_rejected: int
    offset_median_m: float
    offset_p95_m: float
    lateral_offset_m: float = 0.0
    n_considered: int = 0
    odo_span_m: tuple[float, float] = field(default=(0.0, 0.0))

    def chainage(self, odo_m: ArrayLike) -> NDArray[np.float64]:
        """Chainage at odometer distances ``odo_m`` (m), m."""
        o = np.asarray(odo_m, dtype=np.float64)
        # a hinge at a time: a log's worth of samples times every knot would not fit in memory
        c = self.c0_m + self.slope * o
        for b, dk in zip(self.knots_m, self.slope_changes, strict=True):
            c += dk * np.maximum(0.0, o - b)
        return c

    def local_scale(self, odo_m: ArrayLike) -> NDArray[np.float64]:
        """``|dc/d(odo)|`` at odometer distances ``odo_m`` (m): the local odometer scale."""
        o = np.asarray(odo_m, dtype=np.float64)
        k = np.full(o.shape, self.slope)
        for b, dk in zip(self.knots_m, self.slope_changes, strict=True):
            k = k + dk * (o > b)
        return np.abs(k)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready quality indicators and the fitted model."""
        return {
            "method": "gnss",
            "start_chainage_m": self.c0_m,
            "direction": self.direction,
            "scale": self.scale,
            "residual_rms_m": self.residual_rms_m,
            "n_fixes": self.n_fixes,
            "n_considered": self.n_considered,
            "n_used": self.n_used,
            "n_rejected": self.n_rejected,
            "offset_median_m": self.offset_median_m,
            "offset_p95_m": self.offset_p95_m,
            "lateral_offset_m": self.lateral_offset_m,
            "pieces": len(self.knots_m) + 1,
            "knots_m": list(self.knots_m),
        }


def _design(
    odo: NDArray[np.float64], knots: tuple[float, ...] | list[float]
) -> NDArray[np.float64]:
    cols = [np.ones_like(odo), odo, *(np.maximum(0.0, odo - b) for b in knots)]
    return np.column_stack(cols)


def _mad_sigma(r: NDArray[np.float64]) -> float:
    return float(1.4826 * np.median(np.abs(r - np.median(r)))) + 1e-6


def _irls(
    X: NDArray[np.float64], y: NDArray[np.float64], beta: NDArray[np.float64], iters: int = 30
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Huber IRLS from ``beta``; returns the coefficients and the final weights."""
    w = np.ones_like(y)
    for _ in range(iters):
        r = y - X @ beta
        s = _mad_sigma(r)
        a = np.abs(r) / (_HUBER_K * s)
        w = np.where(a <= 1.0, 1.0, 1.0 / np.maximum(a, 1e-12))
        w[np.abs(r) > max(INLIER_M, 4.0 * s)] = 0.0  # gross outliers drop out entirely
        sw = np.sqrt(w)
        new = np.asarray(np.linalg.lstsq(X * sw[:, None], y * sw, rcond=None)[0], np.float64)
        if np.allclose(new, beta, atol=1e-6, rtol=0):
            beta = new
            break
        beta = new
    return beta, w


def _ransac(odo: NDArray[np.float64], ch: NDArray[np.float64]) -> tuple[float, float, int]:
    """Best ``(c0, k)`` over pairs of fixes far apart with a plausible scale, and its inlier
    count (deterministic: a fixed seed)."""
    rng = np.random.default_rng(0)
    n = odo.size
    span = float(odo.max() - odo.min())
    i = rng.integers(0, n, 400)
    j = rng.integers(0, n, 400)
    d = odo[j] - odo[i]
    ok = np.abs(d) > 0.3 * span
    i, j, d = i[ok], j[ok], d[ok]
    k = (ch[j] - ch[i]) / d
    plausible = (np.abs(k) >= SCALE_RANGE[0]) & (np.abs(k) <= SCALE_RANGE[1])
    i, k = i[plausible], k[plausible]
    if k.size == 0:
        return float("nan"), float("nan"), 0
    c0 = ch[i] - k * odo[i]
    sub = np.linspace(0, n - 1, min(n, 2000)).astype(np.int64)  # bounded work on long runs
    resid = np.abs(ch[None, sub] - (c0[:, None] + k[:, None] * odo[None, sub]))
    best = int(np.argmax((resid < INLIER_M).sum(axis=1)))
    count = int(np.sum(np.abs(ch - (c0[best] + k[best] * odo)) < INLIER_M))
    return float(c0[best]), float(k[best]), count


def _n_eff_factor(r: NDArray[np.float64]) -> float:
    """Share of independent information in residuals ordered in time: ``(1 - rho)/(1 + rho)``
    with ``rho`` their lag-1 autocorrelation (an AR(1) approximation)."""
    if r.size < 3:
        return 1.0
    a, b = r[:-1] - r.mean(), r[1:] - r.mean()
    den = float(np.sqrt(np.sum(a * a) * np.sum(b * b))) + 1e-12
    rho = float(np.clip(np.sum(a * b) / den, 0.0, 0.999))
    return (1.0 - rho) / (1.0 + rho)


def _binned(
    odo: NDArray[np.float64], y: NDArray[np.float64], w: NDArray[np.float64], width: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Weighted means of ``odo`` and ``y`` in odometer bins ``width`` m wide, and bin weights."""
    b = np.floor((odo - odo.min()) / width).astype(np.int64)
    sw = np.bincount(b, w).astype(np.float64)
    keep = sw > 0
    mo = np.bincount(b, w * odo)[keep] / sw[keep]
    my = np.bincount(b, w * y)[keep] / sw[keep]
    return mo, my, sw[keep]


def _add_knots(
    odo: NDArray[np.float64], ch: NDArray[np.float64], beta: NDArray[np.float64]
) -> tuple[list[float], NDArray[np.float64], NDArray[np.float64]]:
    """Greedy knots (slope changes) while the effective-sample BIC says the residuals trend.

    The search runs on residuals binned every ``MIN_PIECE_M / 10`` of odometer distance (a
    slope change cannot show within one bin), all candidate knots at once: each candidate's
    hinge is made orthogonal to the current model and its SSR reduction read off.
    """
    knots: list[float] = []
    beta, w = _irls(_design(odo, knots), ch, beta)
    lo, hi = float(odo.min()), float(odo.max())
    max_knots = min(MAX_KNOTS, int((hi - lo) // MIN_PIECE_M) - 1)
    cands = np.arange(lo + MIN_PIECE_M, hi - MIN_PIECE_M + 1e-9, 0.25 * MIN_PIECE_M)
    while len(knots) < max_knots:
        allowed = np.array([all(abs(b - k) >= MIN_PIECE_M for k in knots) for b in cands])
        if not allowed.any():
            break
        used = w > 0
        r = ch - _design(odo, knots) @ beta
        mo, mr, bw = _binned(odo[used], r[used], w[used], MIN_PIECE_M / 10.0)
        bw = bw / bw.mean()
        ssr = float(np.sum(bw * mr * mr))  # between-bin residual: what a trend can explain
        n_eff = max(2.0, mo.size * _n_eff_factor(mr))
        sw = np.sqrt(bw)
        q, _ = np.linalg.qr(_design(mo, knots) * sw[:, None])
        h = np.maximum(0.0, mo[:, None] - cands[None, allowed]) * sw[:, None]
        h -= q @ (q.T @ h)
        norm2 = np.einsum("ij,ij->j", h, h)
        proj = h.T @ (mr * sw)
        gains = np.where(norm2 > 1e-9, proj**2 / np.maximum(norm2, 1e-9), 0.0)
        best = int(np.argmax(gains))
        change = abs(proj[best] / max(norm2[best], 1e-9))  # the slope change it would add
        if gains[best] <= 0 or gains[best] >= ssr or change < MIN_SCALE_CHANGE:
            break
        # BIC with the effective sample size, twice as strict as the textbook penalty
        if n_eff * np.log(ssr / (ssr - gains[best])) <= 2.0 * np.log(n_eff):
            break
        knots = sorted([*knots, float(cands[allowed][best])])
        X = _design(odo, knots)
        sq = np.sqrt(w)
        start = np.asarray(np.linalg.lstsq(X * sq[:, None], ch * sq, rcond=None)[0], np.float64)
        beta, w = _irls(X, ch, start)
    return knots, beta, w


def thin_fixes(
    time_s: ArrayLike,
    has_fix: ArrayLike,
    *,
    interval_s: float = FIX_INTERVAL_S,
    max_fixes: int | None = MAX_FIXES,
) -> NDArray[np.int64]:
    """Indices of the fixes the fit uses: the first fix in each ``interval_s`` of time, the
    interval widened so that at most ``max_fixes`` remain.

    Why the fit loses nothing by it: GNSS receivers give at most 10-20 fixes a second, so a
    log with a fix on every row (1 kHz) repeats or interpolates them; and what limits the fit
    is the fixes' wandering bias (1-3 m, correlated over 10-30 s), not their number: at 10 Hz
    the white part of the error averages to ~1.5 m / sqrt(n) (8 cm over a 1 km run at 30 m/s,
    under 1 cm over an hour), far below the bias. The model's finest detail is a slope change every
    :data:`MIN_PIECE_M` (2 km), searched on bins of a tenth of that (200 m): 10 Hz leaves 20
    fixes per bin at 100 m/s, and :data:`MAX_FIXES` leaves 8 per bin on a 1 000 km run.

    Parameters
    ----------
    time_s : array_like, shape (n,)
        Sample times, s (increasing).
    has_fix : array_like of bool, shape (n,)
        Where the log has a fix.
    interval_s : float
        Shortest time between kept fixes, s (0: keep all).
    max_fixes : int or None
        Most fixes kept (None: no limit).

    Returns
    -------
    ndarray of int
        Sample indices of the kept fixes, increasing.
    """
    idx = np.flatnonzero(np.asarray(has_fix, dtype=bool))
    if idx.size < 2:
        return idx
    t = np.asarray(time_s, dtype=np.float64)[idx]
    span = float(t[-1] - t[0])
    step = max(float(interval_s), span / max_fixes if max_fixes else 0.0)
    if step <= 0:
        return idx
    # rounded, not floored: fixes exactly at the interval (a 10 Hz receiver) all stay, whatever
    # the rounding of their times
    bucket = np.rint((t - t[0]) / step).astype(np.int64)
    first = np.concatenate([[True], bucket[1:] != bucket[:-1]])
    return idx[first]


def place_run(
    centerline: Centerline,
    time_s: ArrayLike,
    odo_m: ArrayLike,
    lat_deg: ArrayLike,
    lon_deg: ArrayLike,
    *,
    max_offset_m: float = MAX_OFFSET_M,
    lateral_tolerance_m: float = LATERAL_TOLERANCE_M,
    fix_interval_s: float = FIX_INTERVAL_S,
    max_fixes: int | None = MAX_FIXES,
    budget: TimeBudget | None = None,
) -> Placement:
    """Fit a run's odometer to its GNSS fixes projected onto the centerline.

    Parameters
    ----------
    centerline : Centerline
        The track's line and chainage.
    time_s : array_like, shape (n,)
        Sample times, s (increasing).
    odo_m : array_like, shape (n,)
        Odometer distance from the first sample, m (integrated speed or the odometer column).
    lat_deg, lon_deg : array_like, shape (n,)
        Fixes, WGS84 degrees, NaN at samples without one.
    max_offset_m : float
        Farthest a fix may lie from the line and still be used, m.
    lateral_tolerance_m : float
        Largest median signed lateral offset of the fixes used, m (:data:`LATERAL_TOLERANCE_M`).
    fix_interval_s, max_fixes : float, int or None
        How the fixes are thinned before they are projected (:func:`thin_fixes`).
    budget : TimeBudget, optional
        Checked between the stages (projection, robust start, piecewise fit).

    Returns
    -------
    Placement

    Raises
    ------
    NoFixes
        No sample has a fix.
    FixesOffLine
        Most fixes lie farther than ``max_offset_m`` from the line (the message gives their
        median distance, and says so when swapping latitude and longitude would fit).
    TooFewFixes
        Fewer than :data:`MIN_FIXES` fixes near the line.
    FixesDoNotFollowLine
        The fixes near the line do not advance along it as the odometer does (no fit with a
        scale within :data:`SCALE_RANGE` explains :data:`MIN_INLIER_FRACTION` of them).
    FixesBesideLine
        The fixes follow the line but a steady offset more than ``lateral_tolerance_m`` to
        one side (a neighbouring track).
    BudgetExceeded
        ``budget`` ran out (checked between stages).
    """
    odo_all = np.asarray(odo_m, dtype=np.float64)
    lat_all = np.asarray(lat_deg, dtype=np.float64)
    lon_all = np.asarray(lon_deg, dtype=np.float64)
    has = np.isfinite(lat_all) & np.isfinite(lon_all)
    n_fixes = int(has.sum())
    if n_fixes == 0:
        raise NoFixes(
            "the log has no GNSS fixes (its latitude and longitude columns are empty): give "
            "start_chainage_m, or fixes to place the run on the centerline"
        )
    kept = thin_fixes(
        np.asarray(time_s, dtype=np.float64), has, interval_s=fix_interval_s,
        max_fixes=max_fixes,
    )  # fmt: skip
    odo, lat, lon = odo_all[kept], lat_all[kept], lon_all[kept]
    n_considered = int(kept.size)
    loc = centerline.locate(lon, lat)
    if budget is not None:
        budget.check("projecting the GNSS fixes onto the centerline")
    near = loc.offset_m <= max_offset_m
    median_off = float(np.median(loc.offset_m))
    if near.sum() < MIN_INLIER_FRACTION * n_considered:
        hint = ""
        swapped = np.abs(lon) <= 90.0
        if swapped.all():
            alt = centerline.locate(lat, lon)
            if float(np.median(alt.offset_m)) <= max_offset_m:
                hint = " (with latitude and longitude swapped they would fit: check the columns)"
        raise FixesOffLine(
            f"the run's GNSS fixes lie a median {median_off:.1f} m from the track's centerline "
            f"(at most {max_offset_m:g} m expected; {int(near.sum())} of {n_considered} fixes "
            f"within "
            f"it){hint}: is this the right track, and its centerline the right line?",
            median_offset_m=median_off,
        )
    if near.sum() < MIN_FIXES:
        raise TooFewFixes(
            f"only {int(near.sum())} GNSS fixes lie within {max_offset_m:g} m of the centerline; "
            f"at least {MIN_FIXES} are needed to fit start, direction and odometer scale"
        )
    o, c = odo[near], loc.chainage_m[near]
    c0, k, count = _ransac(o, c)
    if budget is not None:
        budget.check("the robust start of the GNSS fit")
    if count < MIN_INLIER_FRACTION * o.size:
        k_free = float(np.polyfit(o, c, 1)[0]) if np.ptp(o) > 0 else 0.0
        raise FixesDoNotFollowLine(
            f"the GNSS fixes do not follow the centerline as the odometer does: over "
            f"{np.ptp(o):.0f} m of odometer distance they move {abs(k_free) * np.ptp(o):.0f} m "
            f"along the line (scale {abs(k_free):.2f}, expected {SCALE_RANGE[0]}-"
            f"{SCALE_RANGE[1]}); at most {count} of {o.size} fixes fit one placement. Another "
            "line crossing or alongside, or the wrong track?"
        )
    knots, beta, w = _add_knots(o, c, np.array([c0, k]))
    if budget is not None:
        budget.check("the piecewise GNSS fit")
    slopes = np.cumsum(beta[1:])
    if np.any(np.sign(slopes) != np.sign(k)) or np.any(
        (np.abs(slopes) < SCALE_RANGE[0]) | (np.abs(slopes) > SCALE_RANGE[1])
    ):
        raise FixesDoNotFollowLine(
            f"the GNSS fixes do not follow the centerline steadily: the fitted odometer scale "
            f"varies from {np.abs(slopes).min():.3f} to {np.abs(slopes).max():.3f} along the run "
            f"(expected {SCALE_RANGE[0]}-{SCALE_RANGE[1]})"
        )
    used = w > 0
    r = (c - _design(o, knots) @ beta)[used]
    lo, hi = float(odo_all.min()), float(odo_all.max())
    edges = np.array([lo, *knots, hi])
    lengths = np.diff(edges)
    scale = float(np.sum(np.abs(slopes) * lengths) / max(np.sum(lengths), 1e-9))
    off_used = loc.offset_m[near][used]
    lateral = float(np.median(loc.lateral_m[near][used]))
    if abs(lateral) > lateral_tolerance_m:
        side = "left" if lateral > 0 else "right"
        raise FixesBesideLine(
            f"the run's GNSS fixes follow the track's centerline but a steady "
            f"{abs(lateral):.1f} m to its {side} (median over {int(used.sum())} fixes, looking "
            f"towards increasing chainage; at most {lateral_tolerance_m:g} m expected): the "
            "run looks to be on a neighbouring track. Upload it to that track, correct this "
            "track's centerline, or give start_chainage_m to place it without GNSS",
            median_offset_m=abs(lateral),
            lateral_offset_m=lateral,
        )
    return Placement(
        c0_m=float(beta[0]),
        slope=float(beta[1]),
        knots_m=tuple(float(b) for b in knots),
        slope_changes=tuple(float(x) for x in beta[2:]),
        direction="increasing" if k > 0 else "decreasing",
        scale=scale,
        residual_rms_m=float(np.sqrt(np.mean(r * r))),
        n_fixes=n_fixes,
        n_used=int(used.sum()),
        n_rejected=n_considered - int(used.sum()),
        offset_median_m=float(np.median(off_used)),
        offset_p95_m=float(np.percentile(off_used, 95)),
        lateral_offset_m=lateral,
        n_considered=n_considered,
        odo_span_m=(lo, hi),
    )
