"""Rail geometry vs support stiffness from many passes with different wheel loads.

The loaded level a pass recovers is ``y_j(x) = g(x) - F_j(x) c(x)`` (levels positive up,
``g`` the unloaded geometry common to every pass, ``F_j`` the pass's wheel force, ``c`` the
track's compliance, m/N). In the product's band ``B`` (3-40 m), with ``F_j = Fbar_j + dF_j(x)``
and ``c = c0 + dc(x)`` (``c0`` the nominal compliance),

    B[y_j] + c0 B[dF_j] = B[g] - Fbar_j B[dc] + (second order)

so per chainage point a weighted straight-line fit of the force-corrected levels against the
passes' mean forces gives the geometry (intercept) and the compliance variation (slope).

A pass's force is that of its measured point, shared by the point's wheels (a bogie: two
wheels 1.8-2.6 m apart, each loading the rail at its own position). The level measured is the
mean under those wheels, each the superposition of every wheel's deflection basin. The fit
runs on equivalent point loads ``F_j kappa_j``: ``kappa_j`` makes a pass's dip over a
reference zone that of a point load (1 for a half car's axle, 0.46-0.51 for a bogie,
:func:`point_load_factor`); the dynamic-force correction uses the sinkage of sound track
instead (:func:`uniform_load_factor`). The slope is then a known blend of the passes' own
dips, and the soft spots are fitted with that blend of their wheels. Passes with different
wheels see the geometry through different averages; each is averaged through the others'
wheels (:func:`view_shifts`) so that all share one. The pass weights are the inverse
variances of each pass's residual (run-to-run scatter: speed, dynamics, sensor noise),
estimated from the fit itself when there are more passes than distinct unknowns, else from
the spread of the compliance where zones are looked for. Soft spots are dips of the
compliance (as the level dip they cause under a reference load) fitted with the
beam-on-discrete-supports model (:func:`engine.stiffness.fit_zone`, same band-pass as the
profile). Details and assumptions: docs/method.md.

One module, about 800 lines: the pass model, the per-point fit, the windowing of the
result and the soft-spot extraction share the result object and its grid conventions; split,
each part would import the others' private helpers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import make_interp_spline

from .chainage import PRODUCT_BAND_M, bandpass_distance
from .detect import DetectionConfig, Dip, add_dips, find_dips, robust_baseline, robust_sigma
from .end_rings import EndRingConfig, fit_end_rings
from .errors import ParameterError, check_settings
from .geometry_check import SMOOTH_RAIL_MESSAGE, SMOOTH_RAIL_SIGMA_MM, is_smooth_rail
from .intervals import true_runs
from .matched_dips import matched_dips, matched_scores
from .pass_equalise import EqualiseConfig, equalise_passes
from .passes import Pass, align_passes, column_mean_sd, on_grid, pass_from_result
from .stiffness import InfluenceLine, fit_zone, modal_dips, softening_modes
from .track import TrackParams

__all__ = [
    "NOT_SEPARABLE_MESSAGE", "PRECISION_MESSAGE", "SMOOTH_RAIL_MESSAGE", "SMOOTH_RAIL_SIGMA_MM",
    "Pass", "SeparatedSpot", "SeparationConfig", "SeparationResult", "align_passes",
    "is_smooth_rail", "load_limited", "pass_from_result", "separate",
]  # fmt: skip

NOT_SEPARABLE_MESSAGE = (
    "dips: geometry and stiffness not separable here — needs a pass with a different wheel "
    "load or a survey"
)
"""What the product says where the passes do not span enough wheel load."""

PRECISION_MESSAGE = (
    "stiffness not resolved here: the passes' levels are too uncertain (near the ends of "
    "runs, or too few passes) to separate geometry from stiffness"
)
"""What the product says where the loads differ enough but the levels are too uncertain."""


@dataclass(frozen=True)
class SeparationConfig:
    """Thresholds of the separation.

    Parameters
    ----------
    min_passes : int
        Fewest passes covering a point for it to be separable.
    min_load_ratio : float
        Smallest ratio of the largest to the smallest mean wheel force among a point's passes.
    max_detectable_loss : float
        A point is separable only if the passes would detect a support loss of this fraction
        over a 6 m zone (the uncertainty of the compliance is small enough), 0-1.
    noise_factor : float
        A compliance dip must be deeper than this many standard deviations (the larger of the
        estimator's own and the robust spread of the compliance profile).
    min_loss : float
        Smallest fitted loss reported as a soft spot (fraction).
    confidence_z : float
        Normal quantile of the reported bands (1.96: 95 %).
    prior_noise_mm : float
        Per-pass level noise assumed where the fit has no degrees of freedom left to estimate
        it (two passes or two loads only), mm: the run-to-run floor measured in geometry.md.
    reference_load_n : float
        Load at which compliance dips are expressed as level dips for detection, N.
    edge_factor, edge_decay_m : float
        Error of a pass's level near its ends: ``edge_factor`` times the rail's roughness
        (robust spread of the level about its baseline) at the end, decaying over
        ``edge_decay_m`` (default 1.15 ``lambda_max_m``); measured, docs/method.md.
    end_ring_edge_factor : float
        ``edge_factor`` of a pass whose end rings were fitted (:attr:`Pass.end_rings`): what
        the fit leaves, 0.3-0.5 of the ring at 25-100 m from an end on the peer's (ROSE)
        runs (docs/accuracy.md "The ends' ring as a few shapes").
    end_rings : EndRingConfig
        How the end rings are fitted (:func:`engine.end_rings.fit_end_rings`).
    lambda_min_m, lambda_max_m, taper : float
        The band of the passes' levels (the product's, 3-40 m).
    grid_step_m : float or None
        Step of the common grid, m (default: the first pass's).
    equalise : EqualiseConfig or None
        Each pass's transfer error relative to the others fitted and taken out before the
        fit (:func:`engine.pass_equalise.equalise_passes`); None: the levels as they are.
    matched_lengths_m : tuple of float
        Zone lengths (m) of the filter matched to a zone's dip and to the compliance's own
        coloured noise (:func:`engine.matched_dips.matched_dips`, same ``noise_factor``):
        its dips, and the residual's within ``lambda_max_m / 2`` of an end of the separable
        profile, are the candidates; empty, or too little profile to measure the noise on:
        the residual's dips alone.
    near_end_matched_z : float
        A residual's dip near an end is kept only where that filter's output reaches this
        many of its standard deviations inside the dip: the filter's support is cut there,
        so a zone gives less than ``noise_factor``, but the compliance's long-wave swings
        near the ends give less still (docs/method.md §10); ``-inf`` keeps every one.
    matched_spread_m : float or None
        Window (m) of that filter's running robust spread which, times
        ``matched_local_share``, is used where larger than its spread over the whole profile
        (the compliance's noise follows the rail's roughness along the line; docs/method.md
        §10); None: the whole profile's alone.
    matched_local_share : float
        0-1: a dip must reach ``noise_factor`` times this share of the running spread.
    """

    min_passes: int = 2
    min_load_ratio: float = 1.1
    max_detectable_loss: float = 0.5
    noise_factor: float = 4.5
    min_loss: float = 0.15
    confidence_z: float = 1.96
    prior_noise_mm: float = 0.04
    reference_load_n: float = 100e3
    edge_factor: float = 0.3
    end_ring_edge_factor: float = 0.12
    end_rings: EndRingConfig = field(default_factory=EndRingConfig)
    edge_decay_m: float | None = None
    lambda_min_m: float = PRODUCT_BAND_M[0]
    lambda_max_m: float = PRODUCT_BAND_M[1]
    taper: float = 0.3
    grid_step_m: float | None = None
    equalise: EqualiseConfig | None = field(default_factory=EqualiseConfig)
    matched_lengths_m: tuple[float, ...] = (3.0, 4.5, 6.0, 8.0, 10.0)
    near_end_matched_z: float = 3.75
    matched_spread_m: float | None = 160.0
    matched_local_share: float = 0.7

    def __post_init__(self) -> None:
        checks = {
            "min_passes": self.min_passes >= 2,
            "min_load_ratio": self.min_load_ratio > 1.0,
            "max_detectable_loss": 0.0 < self.max_detectable_loss < 1.0,
            "noise_factor": self.noise_factor > 0,
            "min_loss": 0.0 <= self.min_loss < 1.0,
            "confidence_z": self.confidence_z > 0,
            "prior_noise_mm": self.prior_noise_mm > 0,
            "reference_load_n": self.reference_load_n > 0,
            "edge_factor": self.edge_factor >= 0,
            "end_ring_edge_factor": self.end_ring_edge_factor >= 0,
            "edge_decay_m": self.edge_decay_m is None or self.edge_decay_m > 0,
            "lambda_max_m": 0 < self.lambda_min_m < self.lambda_max_m,
            "grid_step_m": self.grid_step_m is None or 0 < self.grid_step_m <= 1.0,
            "near_end_matched_z": not math.isnan(self.near_end_matched_z),
            "matched_spread_m": self.matched_spread_m is None
            or self.lambda_max_m <= self.matched_spread_m < math.inf,
            "matched_local_share": 0.0 < self.matched_local_share <= 1.0,
            "matched_lengths_m": all(
                math.isfinite(v) and 0 < v < self.lambda_max_m for v in self.matched_lengths_m
            ),
        }
        check_settings(self, checks, "separation")


@dataclass(frozen=True)
class SeparatedSpot:
    """A soft spot found from the separated compliance.

    Attributes
    ----------
    start_m, end_m : float
        Extent (track carried by the softened supports), m.
    peak_m : float
        Chainage of the deepest compliance dip, m.
    loss_pct : float
        Fitted support-stiffness loss, % of nominal.
    loss_lo_pct, loss_hi_pct : float
        Its band at the configured confidence, %.
    confidence : float
        Probability (0-1) that the dip is not estimator noise, from its depth in standard
        deviations.
    depth_mm : float
        Depth of the compliance dip as a level dip under the reference load, mm.
    """

    start_m: float
    end_m: float
    peak_m: float
    loss_pct: float
    loss_lo_pct: float
    loss_hi_pct: float
    confidence: float
    depth_mm: float = float("nan")

    def to_dict(self) -> dict[str, float]:
        """Plain dict of the fields (floats)."""
        return {k: float(getattr(self, k)) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class SeparationResult:
    """Per-chainage geometry, compliance and relative stiffness from the passes.

    Attributes
    ----------
    chainage_m : ndarray
        Common grid, m.
    geometry_mm, geometry_sd_mm : ndarray
        Unloaded geometry in the band (mm, positive up) and its standard deviation, as every
        pass's wheels together see it (:func:`view_shifts`; the rail itself when every pass
        has one wheel at its measured point). Where not separable, the mean force-corrected
        loaded level assuming nominal stiffness.
    k_rel, k_rel_lo, k_rel_hi : ndarray
        Support stiffness over nominal and its band (NaN where not separable). Outside soft
        spots ``k_rel`` is 1 and ``k_rel_lo`` is 1 minus the smallest loss the passes would
        have detected there.
    compliance_mm_per_kn : ndarray
        Nominal compliance plus its estimated variation in the band, mm/kN (NaN where not
        separable).
    compliance_sd_mm_per_kn : ndarray
        Standard deviation of the compliance variation, mm/kN.
    n_passes : ndarray of int
        Passes covering each point.
    load_ratio : ndarray
        Largest over smallest mean wheel force of the passes covering each point.
    separable : ndarray of bool
        Whether geometry and stiffness are separable at each point.
    message : str or None
        Plain words when some covered point is not separable.
    soft_spots : list of SeparatedSpot
        Significant support-stiffness losses.
    contributors : list of (label, kind, mean_force_n)
        The passes used.
    dips : list of Dip
        Where not separable: dips of the mean loaded level by depth only (no loss figure).
    config : SeparationConfig
        The thresholds used.
    """

    chainage_m: NDArray[np.float64]
    geometry_mm: NDArray[np.float64]
    geometry_sd_mm: NDArray[np.float64]
    k_rel: NDArray[np.float64]
    k_rel_lo: NDArray[np.float64]
    k_rel_hi: NDArray[np.float64]
    compliance_mm_per_kn: NDArray[np.float64]
    compliance_sd_mm_per_kn: NDArray[np.float64]
    n_passes: NDArray[np.int64]
    load_ratio: NDArray[np.float64]
    separable: NDArray[np.bool_]
    message: str | None
    soft_spots: list[SeparatedSpot]
    contributors: list[tuple[str, str, float]]
    dips: list[Dip] = field(default_factory=list)
    config: SeparationConfig = field(default_factory=lambda: SeparationConfig())

    def window(self, from_m: float, to_m: float) -> SeparationResult:
        """The part of the result in ``[from_m, to_m]`` (m); spots and dips that overlap it."""
        lo, hi = np.searchsorted(self.chainage_m, [from_m, to_m + 1e-9])
        sl = slice(int(lo), int(hi))
        arrays = {
            name: getattr(self, name)[sl]
            for name in (
                "chainage_m", "geometry_mm", "geometry_sd_mm", "k_rel", "k_rel_lo", "k_rel_hi",
                "compliance_mm_per_kn", "compliance_sd_mm_per_kn", "n_passes", "load_ratio",
                "separable",
            )
        }  # fmt: skip
        return replace(
            self,
            **arrays,
            message=_message(
                arrays["n_passes"], arrays["load_ratio"], arrays["separable"], self.config
            ),  # fmt: skip
            soft_spots=[s for s in self.soft_spots if s.end_m >= from_m and s.start_m <= to_m],
            dips=[d for d in self.dips if d.end_m >= from_m and d.start_m <= to_m],
        )


def _message(
    n_passes: NDArray[np.int64],
    load_ratio: NDArray[np.float64],
    separable: NDArray[np.bool_],
    cfg: SeparationConfig,
) -> str | None:
    """The plain-words message for the covered points that are not separable (None if all are)."""
    lacking = (n_passes > 0) & ~separable
    if not lacking.any():
        return None
    limited = load_limited(n_passes, load_ratio, cfg)
    return NOT_SEPARABLE_MESSAGE if np.any(lacking & limited) else PRECISION_MESSAGE


def load_limited(
    n_passes: NDArray[np.int64] | NDArray[np.float64],
    load_ratio: NDArray[np.float64],
    cfg: SeparationConfig | None = None,
) -> NDArray[np.bool_]:
    """Where a point that is not separable lacks passes or wheel load (the ``load`` reason);
    elsewhere a point that is not separable lacks precision. The one rule for why."""
    c = cfg or SeparationConfig()
    with np.errstate(invalid="ignore"):
        return np.asarray((n_passes < c.min_passes) | ~(load_ratio >= c.min_load_ratio))


EXTENT_TREND_ORDER = 1
"""Order of the trend fitted with a zone's extent and loss (:func:`engine.stiffness.fit_zone`
``trend_order``): a level and a slope across the window, the compliance's long-wave noise
there. The loss's confidence bounds are fitted on the extent found without it, as before."""

REFERENCE_ZONE_LOSS = 0.45
"""Loss of the 6 m reference zone on which passes with different wheels are made comparable."""

_LOSSES = np.linspace(0.0, 0.9, 19)


@lru_cache(maxsize=32)
def zone_depths(
    params: TrackParams,
    lambda_min: float,
    lambda_max: float,
    taper: float,
    wheel_offsets_m: tuple[float, ...] = (0.0,),
    shifts_m: tuple[float, ...] = (0.0,),
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Depth of the band-passed level dip of a 6 m zone against its loss, when the wheels at
    ``wheel_offsets_m`` (m) share a force of 1 N and the level is averaged over ``shifts_m``
    (m, :func:`view_shifts`): the losses (0-0.9) and the depths, mm/N.

    The mean level under the wheels is the single-load formula with the wheels' summed
    influence (:func:`engine.stiffness.fit_zone`, Notes); a shift moves the whole set.
    """
    step = 0.25
    grid = np.arange(-60.0, 60.0 + step / 2, step)
    infl = InfluenceLine(params)
    offsets = np.asarray(wheel_offsets_m, dtype=float)
    sup_x = params.spacing * np.arange(np.ceil(-3.0 / params.spacing - 1e-9),
                                       np.floor(3.0 / params.spacing + 1e-9) + 1)  # fmt: skip
    flex = infl(sup_x[None, :] - sup_x[:, None])
    modes = []
    for t in shifts_m:
        B = np.sum([infl(grid[None, :] + o + t - sup_x[:, None]) for o in offsets], axis=0)
        lam, E = softening_modes(flex, B, np.eye(grid.size))
        modes.append(E)
    d = modal_dips(lam, np.mean(modes, axis=0), _LOSSES, params.k_nominal, 1.0 / offsets.size**2)
    depths = np.array(
        [-float(np.nanmin(bandpass_distance(row, step, lambda_min, lambda_max, taper)))
         for row in d]
    )  # fmt: skip
    depths[0] = 0.0
    return _LOSSES, depths


def point_load_factor(
    params: TrackParams,
    wheel_offsets_m: tuple[float, ...],
    lambda_min: float = PRODUCT_BAND_M[0],
    lambda_max: float = PRODUCT_BAND_M[1],
    taper: float = 0.3,
    shifts_m: tuple[float, ...] = (0.0,),
) -> float:
    """``kappa``: the point load, per N of a measured point's force shared by its wheels,
    that makes the same band-passed dip over the reference zone (6 m, 45 %).

    1 for one wheel. A bogie's two wheels each carry half the force and superpose their
    deflection basins, smoothed over the wheelbase: 0.46-0.51 for 2.6-1.8 m on the nominal
    track. On the reference zone passes with different wheels then give the same
    compliance dip per unit of their equivalent force; on a zone of 4-8 m the wheelbases of
    1.9 and 2.6 m still differ by 5 % or less. ``shifts_m`` (m): the level is averaged over
    these shifts (:func:`view_shifts`).
    """
    i = int(np.argmin(np.abs(_LOSSES - REFERENCE_ZONE_LOSS)))
    own = zone_depths(
        params, lambda_min, lambda_max, taper, tuple(wheel_offsets_m), tuple(shifts_m)
    )[1][i]
    point = zone_depths(params, lambda_min, lambda_max, taper)[1][i]
    return float(own / point)


def uniform_load_factor(infl: InfluenceLine, wheel_offsets_m: tuple[float, ...]) -> float:
    """The mean nominal rail level under a measured point's wheels, each carrying an equal
    share of its force, over the level under that force as one point load (the sinkage a
    changing force causes away from soft zones): ``(1 + f(a) / f(0)) / 2`` for two wheels
    ``a`` apart, ``f`` the influence line."""
    o = np.asarray(wheel_offsets_m, dtype=float)
    return float(infl(o[:, None] - o[None, :]).sum() / (o.size**2 * infl(np.zeros(1))[0]))


def view_shifts(wheel_offsets: Sequence[tuple[float, ...]]) -> list[tuple[float, ...]]:
    """Per pass, the shifts (m) over which its level is averaged so that every pass sees the
    geometry through the same wheels.

    A pass's level holds the geometry averaged under its own wheels (``A_j g``: the mean of
    ``g`` at the wheel offsets). A coach's bogie (2.6 m) and a wagon's (1.9 m) see the same
    rail differently at 3-8 m wavelengths (2.6 m cancels 5.2 m), by about as much as a
    zone's deflection differs between them: the separation would read that as compliance.
    The averages commute, so averaging each pass over every *other* distinct set of wheels
    gives all of them the same ``(prod_k A_k) g``. Sets are told apart to 1 mm; a single
    wheel at the measured point averages nothing (passes that all have one change nothing).
    """
    keys = [tuple(sorted(round(float(o), 3) for o in w)) for w in wheel_offsets]
    distinct = [k for k in dict.fromkeys(keys) if k != (0.0,)]
    out: list[tuple[float, ...]] = []
    for key in keys:
        shifts: tuple[float, ...] = (0.0,)
        for other in distinct:
            if other != key:
                shifts = tuple(t + o for t in shifts for o in other)
        out.append(shifts)
    return out


def _shift_mean(
    grid: NDArray[np.float64], y: NDArray[np.float64], shifts: tuple[float, ...]
) -> NDArray[np.float64]:
    """``y`` (on the regular ``grid``, m) averaged over ``y(x + t)`` for ``t`` in ``shifts``
    (m); NaN where a shifted point leaves the covered part (or comes within two steps of a
    gap). Cubic-spline interpolation between grid points: a shift is rarely a whole step, and
    linear interpolation would damp 3 m waves by up to 3 %."""
    if shifts == (0.0,):
        return y
    ok = np.isfinite(y)
    if ok.sum() < 8:
        return np.full_like(y, np.nan)
    idx = np.flatnonzero(ok)
    # gaps and ends filled smoothly so the spline does not ring off a jump
    spline = make_interp_spline(grid, np.interp(grid, grid[idx], y[idx]), k=3)
    out = np.mean([spline(grid + t) for t in shifts], axis=0)
    clear = np.convolve(ok.astype(float), np.ones(5), mode="same") > 4.5
    valid = np.ones(grid.size, dtype=bool)
    for t in shifts:
        valid &= np.interp(grid + t, grid, clear.astype(float), left=0.0, right=0.0) > 0.999
    return np.where(valid, out, np.nan)


def _edge_variance(
    grid: NDArray[np.float64],
    levels: NDArray[np.float64],
    step: float,
    cfg: SeparationConfig,
    factors: Sequence[float],
) -> NDArray[np.float64]:
    """Variance of each pass's level error near its ends, mm² (passes x points).

    ``(factors[j] * sigma_j * exp(-d / edge_decay_m))²`` with ``d`` the distance to the
    nearer end of the pass's coverage and ``sigma_j`` the robust spread of its band-passed
    level (the rail's roughness as this pass sees it); ``factors[j]`` the config's
    ``edge_factor``, or ``end_ring_edge_factor`` for a pass whose end rings were fitted.
    """
    out = np.zeros_like(levels)
    decay = cfg.edge_decay_m if cfg.edge_decay_m is not None else 1.15 * cfg.lambda_max_m
    for j in range(levels.shape[0]):
        ok = np.isfinite(levels[j])
        if not ok.any():
            continue
        idx = np.flatnonzero(ok)
        d = np.minimum(grid - grid[idx[0]], grid[idx[-1]] - grid)
        # every 4th point (1 m) is plenty for a robust spread of a band-passed level
        sigma = robust_sigma(levels[j, ::4])
        out[j] = np.where(ok, (factors[j] * sigma * np.exp(-np.maximum(d, 0) / decay)) ** 2, 0)
    return out


def _weighted_fit(
    z: NDArray[np.float64], fbar: NDArray[np.float64], weights: NDArray[np.float64]
) -> tuple[NDArray[np.float64], ...]:
    """Per point, weighted least squares of ``z_j = a - Fbar_j b`` over the covering passes.

    ``weights`` (passes x points) are inverse variances, 1/mm². Returns a, b (mm/N), their
    variances, the weighted mean force, the residuals and the count of covering passes.
    """
    cov = np.isfinite(z)
    W = np.where(cov, weights, 0.0)
    F = np.broadcast_to(fbar[:, None], z.shape)
    zz = np.where(cov, z, 0.0)
    sw = W.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        fm = (W * F).sum(axis=0) / sw
        zm = (W * zz).sum(axis=0) / sw
        dF = np.where(cov, F - fm, 0.0)
        sxx = (W * dF**2).sum(axis=0)
        b = -(W * dF * (zz - zm)).sum(axis=0) / sxx
        a = zm + b * fm
        var_b = 1.0 / sxx
        var_a = 1.0 / sw + fm**2 * var_b
    resid = np.where(cov, z - (a - F * b), np.nan)
    return a, b, var_a, var_b, fm, resid, cov.sum(axis=0)


def separate(
    passes: Sequence[Pass], track: TrackParams | None = None, config: SeparationConfig | None = None
) -> SeparationResult:
    """Separate unloaded geometry from support stiffness over aligned passes.

    Parameters
    ----------
    passes : sequence of Pass
        Aligned passes (runs and surveys), levels in mm in the band, forces in N.
    track : TrackParams, optional
        Nominal rail and support properties (default UIC60 on 80 kN/mm).
    config : SeparationConfig, optional
        Thresholds.

    Returns
    -------
    SeparationResult
    """
    cfg = config or SeparationConfig()
    trk = track or TrackParams()
    if len(passes) == 0:
        raise ParameterError("separation needs at least one pass")
    step = cfg.grid_step_m or float(passes[0].chainage_m[1] - passes[0].chainage_m[0])
    # the passes' end rings (where their shapes are given) off their levels, before all else
    passes = fit_end_rings(passes, cfg.end_rings)
    edge_factors = [
        cfg.edge_factor if p.end_rings is None else cfg.end_ring_edge_factor for p in passes
    ]
    grid, levels, forces = on_grid(passes, step)
    n_pass = len(passes)
    infl = InfluenceLine(trk)
    band = (cfg.lambda_min_m, cfg.lambda_max_m, cfg.taper)
    sink, kappa = np.ones(n_pass), np.ones(n_pass)
    for j, p in enumerate(passes):
        _check_wheels(j, p)
    shifts = view_shifts([p.wheel_offsets_m for p in passes])
    for j, p in enumerate(passes):
        sink[j] = uniform_load_factor(infl, p.wheel_offsets_m)
        kappa[j] = point_load_factor(trk, p.wheel_offsets_m, *band, shifts_m=shifts[j])
    fbar = np.array([float(np.nanmean(f)) if np.isfinite(f).any() else np.nan for f in forces])
    c0 = float(infl(np.zeros(1))[0]) * 1e3  # mm/N
    # force correction: the nominal track's deflection under each pass's dynamic force
    z = levels.copy()
    for j in range(n_pass):
        df = forces[j] - fbar[j]
        if np.isfinite(df).sum() >= 8:
            z[j] = levels[j] + sink[j] * c0 * bandpass_distance(
                df, step, cfg.lambda_min_m, cfg.lambda_max_m, cfg.taper
            )
        # every pass sees the geometry through every vehicle's wheels (view_shifts)
        z[j] = _shift_mean(grid, z[j], shifts[j])
    contributors = [(p.label, p.kind, float(fbar[j])) for j, p in enumerate(passes)]
    # from here on every force is the equivalent point load (the fit's and the message's)
    fbar = fbar * kappa
    cov = np.isfinite(z)
    n_cov = cov.sum(axis=0)
    with np.errstate(invalid="ignore"):
        fmax = np.nanmax(np.where(cov, fbar[:, None], np.nan), axis=0, initial=-np.inf)
        fmin = np.nanmin(np.where(cov, fbar[:, None], np.nan), axis=0, initial=np.inf)
        ratio = np.where(n_cov > 0, fmax / fmin, np.nan)

    # near a pass's ends the inversion's band edges ring over ~lambda_max: an error growing
    # with the rail's roughness (docs/method.md, measured) enters as extra variance
    viewed = np.array([_shift_mean(grid, levels[j], shifts[j]) for j in range(n_pass)])
    edge_var = _edge_variance(grid, viewed, step, cfg, edge_factors)
    if cfg.equalise is not None:
        trust = cfg.prior_noise_mm**2 / (cfg.prior_noise_mm**2 + edge_var)
        z = equalise_passes(z, step, cfg.lambda_min_m, cfg.lambda_max_m, trust, fbar,
                            cfg.equalise).levels_mm  # fmt: skip
    # per-pass noise from the residuals (two rounds); the prior where no dof is left
    noise_mm = np.full(n_pass, cfg.prior_noise_mm)
    fit_ok = (n_cov >= 2) & (ratio > 1.0 + 1e-6)
    estimated = np.zeros(n_pass, dtype=bool)
    for _ in range(2):
        weights = 1.0 / (noise_mm[:, None] ** 2 + edge_var)
        a, b, var_a, var_b, fm, resid, _n = _weighted_fit(z, fbar, weights)
        dof = n_cov - 2
        new = np.empty(n_pass)
        for j in range(n_pass):
            use = cov[j] & fit_ok & (dof > 0) & (edge_var[j] < noise_mm[j] ** 2)
            estimated[j] = use.sum() >= 40
            if not estimated[j]:
                new[j] = cfg.prior_noise_mm
                continue
            # residual variance scaled up for the fitted parameters' share (n / (n - 2))
            scale = float(np.mean(n_cov[use] / np.maximum(dof[use], 1)))
            sig = robust_sigma(resid[j, use][::4])
            new[j] = max(sig * math.sqrt(scale), 0.25 * cfg.prior_noise_mm)
        noise_mm = new

    with np.errstate(invalid="ignore"):  # each pass's coefficient in the slope
        coef = np.where(np.isfinite(z) & fit_ok, weights * (fbar[:, None] - fm) * var_b, 0.0)
    wheels = _slope_wheel_sets(passes, shifts, np.nan_to_num(coef), fbar)
    if not estimated.any():
        with np.errstate(invalid="ignore"):
            edge_excess = np.max(np.where(cov, edge_var / noise_mm[:, None] ** 2, 0.0), axis=0)
        s2 = _band_noise_scale(grid, b, np.sqrt(var_b), np.where(fit_ok, edge_excess, np.inf)) ** 2
        var_a, var_b = var_a * s2, var_b * s2
    sd_b = np.sqrt(var_b)  # mm/N
    losses = zone_depths(trk, *band)[0]
    depths = cfg.reference_load_n * sum(
        alpha * zone_depths(trk, *band, o, t)[1] / point_load_factor(trk, o, *band, shifts_m=t)
        for (o, t), alpha in wheels
    )
    dip_mm = -cfg.reference_load_n * b  # level dip under the reference load (negative = soft)
    dip_sd = cfg.reference_load_n * sd_b
    with np.errstate(invalid="ignore"):
        min_loss = np.interp(cfg.noise_factor * dip_sd, depths, losses, right=1.0)
    separable = (
        (n_cov >= cfg.min_passes)
        & (ratio >= cfg.min_load_ratio)
        & np.isfinite(b)
        & (min_loss <= cfg.max_detectable_loss)
    )

    # geometry: the intercept where separable; else the mean corrected level (nominal stiffness)
    zmean, zsd = column_mean_sd(z)
    geometry = np.where(separable, a, zmean)
    geometry_sd = np.where(separable, np.sqrt(var_a), np.maximum(zsd, noise_mm.mean()))
    geometry = np.where(n_cov > 0, geometry, np.nan)
    geometry_sd = np.where(n_cov > 0, geometry_sd, np.nan)

    spots: list[SeparatedSpot] = []
    k_rel = np.where(separable, 1.0, np.nan)
    k_lo = np.where(separable, 1.0 - min_loss, np.nan)
    k_hi = np.where(separable, 1.0, np.nan)
    if separable.any():
        spots = _soft_spots(grid, np.where(separable, dip_mm, np.nan), dip_sd, trk, cfg, wheels)
        for s in spots:
            inside = (grid >= s.start_m) & (grid <= s.end_m)
            k_rel[inside] = 1.0 - s.loss_pct / 100
            k_lo[inside] = 1.0 - s.loss_hi_pct / 100
            k_hi[inside] = 1.0 - s.loss_lo_pct / 100

    compliance = np.where(separable, (c0 + b) * 1e3, np.nan)
    compliance_sd = np.where(separable, sd_b * 1e3, np.nan)
    covered = n_cov > 0
    message = _message(n_cov, ratio, separable, cfg)
    dips: list[Dip] = []
    if message is not None:
        mean_level = np.where(covered & ~separable, column_mean_sd(levels)[0], np.nan)
        det = DetectionConfig()
        resid_level = mean_level - robust_baseline(mean_level, step, det.baseline_window_m)
        dips, _ = find_dips(grid, resid_level, det)
    return SeparationResult(
        chainage_m=grid,
        geometry_mm=geometry,
        geometry_sd_mm=geometry_sd,
        k_rel=k_rel,
        k_rel_lo=k_lo,
        k_rel_hi=k_hi,
        compliance_mm_per_kn=compliance,
        compliance_sd_mm_per_kn=compliance_sd,
        n_passes=n_cov.astype(np.int64),
        load_ratio=ratio,
        separable=separable,
        message=message,
        soft_spots=spots,
        contributors=contributors,
        dips=dips,
        config=cfg,
    )


def _band_noise_scale(
    grid: NDArray[np.float64],
    dip_mm: NDArray[np.float64],
    dip_sd: NDArray[np.float64],
    edge_excess: NDArray[np.float64],
) -> float:
    """How much larger the noise of the compliance profile is, where a zone's dip is looked
    for, than the fit's own estimate from the prior per-pass noise.

    With no residual left (two passes, or two loads) the passes' noise is a prior: a
    broadband floor, while soft spots are found after removing a 40 m baseline
    (:func:`_soft_spots`), where the inversion's long-wave errors have gone. The measure is
    the robust spread of that baseline-free profile over the points clear of the passes'
    ends (zones are sparse; a track full of them reads noisier, the safe side), over the
    median of the fit's standard deviation there; 1 with less than 40 m of fitted profile.

    ``edge_excess`` is, per point, the largest ratio of a covering pass's edge variance to
    its noise variance (infinite where the fit is not made): the points under 1 are clear.
    Where they span less than 40 m (a short run on rough rail: the edge term of a 1.5 mm
    rail stays above a 0.04 mm prior for 110 m from each end) the 40 m least affected by the
    ends are measured instead; the spread is relative to the fit's own standard deviation,
    which holds the edge term, so it does not grow with it.
    """
    step = float(grid[1] - grid[0])
    need = int(math.ceil(40.0 / step - 1e-9))
    fitted = np.isfinite(dip_mm) & np.isfinite(dip_sd) & np.isfinite(edge_excess)
    if fitted.sum() < need:
        return 1.0
    ok = fitted & (edge_excess < 1.0)
    if ok.sum() < need:
        least = np.argsort(np.where(fitted, edge_excess, np.inf), kind="stable")[:need]
        ok = np.zeros_like(fitted)
        ok[least] = True
    resid = dip_mm - robust_baseline(np.where(ok, dip_mm, np.nan), step, 40.0)
    spread = robust_sigma(resid[ok])
    own = float(np.median(dip_sd[ok]))
    return max(spread / own, 0.25) if own > 0 and math.isfinite(spread) else 1.0


def _check_wheels(j: int, p: Pass) -> None:
    """Pass ``j``'s wheel offsets: finite, some, within 10 m of the measured point."""
    o = p.wheel_offsets_m
    if len(o) == 0 or not all(math.isfinite(v) for v in o) or max(map(abs, o)) > 10.0:
        raise ParameterError(
            f"{p.label or f'pass {j} ({p.kind})'}: wheel_offsets_m must be the finite offsets "
            f"of the measured point's wheels from it, m, within 10 m, got {o!r}",
            field="wheel_offsets_m",
        )


_View = tuple[tuple[float, ...], tuple[float, ...]]
"""How a pass sees the rail: its wheels' offsets and the shifts its level is averaged over, m."""


def _slope_wheel_sets(
    passes: Sequence[Pass],
    shifts: Sequence[tuple[float, ...]],
    a: NDArray[np.float64],
    fbar: NDArray[np.float64],
) -> tuple[tuple[_View, float], ...]:
    """What the fitted slope is made of: per view (wheel offsets and the shifts of
    :func:`view_shifts`, m) its share ``alpha``.

    The slope is ``b = sum_j a_j z_j`` with ``a_j = w_j (Fbar_j - Fmean) / Sxx``, so each
    pass's compliance dip enters it with ``alpha_j = a_j Fbar_j`` (summing to 1): with a
    coach at half a wagon's load, the wagon's wheels with about 2 and the coach's with
    about -1. ``a`` (passes x points) is zero at the points not used; ``alpha`` is averaged
    over the points used and summed per set of wheels.
    """
    used = max(int(np.any(a != 0, axis=0).sum()), 1)
    alpha = np.nan_to_num(a * fbar[:, None]).sum(axis=1) / used
    by_view: dict[_View, float] = {}
    for p, t, v in zip(passes, shifts, alpha, strict=True):
        key = (tuple(float(o) for o in p.wheel_offsets_m), tuple(t))
        by_view[key] = by_view.get(key, 0.0) + float(v)
    sets = tuple((k, v) for k, v in by_view.items() if v != 0.0)
    return sets or ((((0.0,), (0.0,)), 1.0),)


def _zone_shapes(
    step: float, trk: TrackParams, wheels: tuple[tuple[_View, float], ...], cfg: SeparationConfig
) -> list[tuple[float, NDArray[np.float64]]]:
    """Per zone length of ``cfg.matched_lengths_m``, the shape of its compliance dip under
    the blend of wheels the slope is made of (:func:`_slope_wheel_sets`), band-passed as the
    profile, on a grid of ``step`` (m), peak 1.

    Small losses: a support at ``s`` gives way under wheels at ``x + o_k`` by ``sum_k f(x + o_k
    - s)`` (``f`` the nominal influence line) and lowers their mean level by the same sum
    again, so a zone dips ``sum_s (sum_k f)^2``, a box of the zone's length smoothed by the
    squared basin; a matched filter needs the shape, not the depth.
    """
    infl = InfluenceLine(trk)
    x = np.arange(-30.0, 30.0 + step / 2, step)
    basin = np.zeros_like(x)
    for (offsets, shifts), alpha in wheels:
        for t in shifts:
            basin += alpha * sum(infl(x + o + t) for o in offsets) ** 2 / len(shifts)
    out = []
    for length in cfg.matched_lengths_m:
        dip = np.convolve((np.abs(x) <= length / 2).astype(float), basin, mode="same")
        dip = bandpass_distance(dip, step, cfg.lambda_min_m, cfg.lambda_max_m, cfg.taper)
        out.append((float(length), dip / float(np.max(np.abs(dip)))))
    return out


def _near_end(
    grid: NDArray[np.float64], profile: NDArray[np.float64], distance_m: float
) -> NDArray[np.bool_]:
    """Where ``profile`` is defined within ``distance_m`` (m) of an end of its run of
    defined points (on the regular ``grid``, m)."""
    out = np.zeros(grid.size, dtype=bool)
    for a, b in true_runs(np.isfinite(profile)):
        x = grid[a:b]
        out[a:b] = np.minimum(x - x[0], x[-1] - x) <= distance_m
    return out


def _seen_by_filter(
    grid: NDArray[np.float64],
    scaled: NDArray[np.float64],
    dips: list[Dip],
    shapes: list[tuple[float, NDArray[np.float64]]],
    cfg: SeparationConfig,
) -> list[Dip]:
    """The residual's dips near an end of the separable profile ``scaled`` (on ``grid``, m)
    in which the filter matched to the zone ``shapes`` reaches ``cfg.near_end_matched_z``.

    The filter's support is cut near an end, so a zone there gives it less than it would
    inside; the compliance's 10-40 m swings, which grow towards the ends with the passes'
    edge errors, give the residual's threshold broad dips that the filter, weighing those
    wavelengths by the noise, hardly sees (docs/method.md §10).
    """
    scores = matched_scores(
        grid, scaled, shapes, cfg.lambda_max_m, cfg.matched_spread_m, cfg.matched_local_share
    )
    if scores is None:
        return dips
    out = []
    for d in dips:
        inside = (grid >= d.start_m) & (grid <= d.end_m) & np.isfinite(scores)
        if inside.any() and float(np.max(scores[inside])) >= cfg.near_end_matched_z:
            out.append(d)
    return out


def _soft_spots(
    grid: NDArray[np.float64],
    dip_mm: NDArray[np.float64],
    dip_sd: NDArray[np.float64],
    trk: TrackParams,
    cfg: SeparationConfig,
    wheels: tuple[tuple[_View, float], ...] = ((((0.0,), (0.0,)), 1.0),),
) -> list[SeparatedSpot]:
    """Significant compliance dips, fitted with the beam-on-supports model under the blend
    of wheels the slope is made of (:func:`_slope_wheel_sets`), each set's force the
    equivalent of the reference load; a view's shifts are its wheels moved together, each
    with an equal share."""
    step = float(grid[1] - grid[0])
    resid = dip_mm - robust_baseline(dip_mm, step, 40.0)
    spread = robust_sigma(resid)
    sd_eff = np.maximum(np.where(np.isfinite(dip_sd), dip_sd, np.inf), spread)
    det = DetectionConfig(noise_factor=cfg.noise_factor, min_depth_mm=1e-6)
    # local threshold: scale by the local standard deviation before the detector
    scaled = resid / sd_eff
    cand, _ = find_dips(grid, scaled, replace(det, noise_factor=1.0, min_depth_mm=cfg.noise_factor))
    band = (cfg.lambda_min_m, cfg.lambda_max_m, cfg.taper)
    if cfg.matched_lengths_m:
        # the compliance's noise is coloured (the passes' long-wave errors differenced): a
        # filter matched to it and to a zone's dip sees zones the white threshold misses
        shapes = _zone_shapes(step, trk, wheels, cfg)
        found = matched_dips(
            grid,
            scaled,
            shapes,
            cfg.noise_factor,
            cfg.lambda_max_m,
            cfg.matched_spread_m,
            cfg.matched_local_share,
        )
        if found is not None:
            # the residual's own dips only where the filter's view is cut: within half the
            # baseline window of an end of the separable profile (elsewhere its long-wave
            # excursions are what the filter tells from zones)
            near = _near_end(grid, scaled, 0.5 * cfg.lambda_max_m)
            cand = [d for d in cand if near[int(np.argmin(np.abs(grid - d.peak_m)))]]
            if cand and cfg.near_end_matched_z > -math.inf:
                cand = _seen_by_filter(grid, scaled, cand, shapes, cfg)
            cand = add_dips(grid, scaled, cand, found)
    sets = tuple(
        (
            tuple(w + t for w in o),
            alpha
            * cfg.reference_load_n
            / (len(o) * len(ts) * point_load_factor(trk, o, *band, shifts_m=ts)),
        )
        for (o, ts), alpha in wheels
        for t in ts
    )
    load = cfg.reference_load_n
    half = 0.5 * trk.spacing
    out: list[SeparatedSpot] = []
    for d in cand:
        with np.errstate(divide="ignore", invalid="ignore"):
            # the compliance's noise is mostly 10-40 m long: across the fitted window it is
            # a level and a slope, which a plain misfit reads as a longer zone on its low
            # side; fitted as a nuisance, the ends follow the dip (method.md §10)
            f = fit_zone(grid, resid, d.start_m, d.end_m, trk, load, cfg.lambda_min_m,
                         cfg.lambda_max_m, taper=cfg.taper, wheel_sets=sets,
                         trend_order=EXTENT_TREND_ORDER)  # fmt: skip
        if not math.isfinite(f.loss) or f.loss < cfg.min_loss:
            continue
        zone = (grid >= f.start_m - 3.0) & (grid <= f.end_m + 3.0)
        sd_zone = float(np.nanmedian(sd_eff[zone])) if zone.any() else spread
        shift = cfg.confidence_z * sd_zone
        near = np.abs(grid - 0.5 * (f.start_m + f.end_m)) <= 0.5 * (f.end_m - f.start_m) + 3.0
        deeper = np.where(near, resid - shift, resid)
        shallower = np.where(near, resid + shift, resid)
        with np.errstate(divide="ignore", invalid="ignore"):  # a loss scanned down to 0
            hi = fit_zone(grid, deeper, f.start_m, f.end_m, trk, load, cfg.lambda_min_m,
                          cfg.lambda_max_m, taper=cfg.taper, refine_extent=False,
                          wheel_sets=sets)  # fmt: skip
            lo = fit_zone(grid, shallower, f.start_m, f.end_m, trk, load, cfg.lambda_min_m,
                          cfg.lambda_max_m, taper=cfg.taper, refine_extent=False,
                          wheel_sets=sets)  # fmt: skip
        if lo.loss <= 0.0:
            continue
        k = int(np.argmin(np.abs(grid - d.peak_m)))
        depth = float(-resid[k])
        z = depth / sd_zone
        conf = 0.5 * (1.0 + math.erf((z - cfg.noise_factor / 2) / math.sqrt(2.0)))
        out.append(
            SeparatedSpot(
                start_m=f.start_m - half,
                end_m=f.end_m + half,
                peak_m=d.peak_m,
                loss_pct=100.0 * f.loss,
                loss_lo_pct=100.0 * min(lo.loss, f.loss),
                loss_hi_pct=100.0 * max(hi.loss, f.loss),
                confidence=conf,
                depth_mm=depth,
            )
        )
    return out
