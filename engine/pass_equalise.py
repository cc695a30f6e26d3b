"""Each pass's own transfer error, estimated from the passes together and taken out.

A pass's level is the rail's loaded level seen through the inversion of its vehicle; a
vehicle a little off its registration (10 % in a mass or a spring, as in a real fleet) turns
that into ``y_j = H_j (g - F_j c)``: a smooth gain and phase ``H_j(lambda)`` near 1, different
per vehicle and speed. Over rough rail the geometry ``g`` (about 1 mm) is common to every pass
and dominates the 3-40 m band, so ``H_j - H_k`` times it (0.04-0.25 mm) reads as compliance
in the separation, while a soft zone's deflection is local (a few metres, 0.1-0.5 mm).

So each pass's transfer relative to the passes' mean is fitted on the passes themselves: the
level against the mean level filtered by a few smooth basis functions of the wavelength
(hat functions at log-spaced wavelengths, a gain and a quadrature part each), robustly
(Tukey's bisquare: the zones' local dips, where the passes differ by their load, get no
weight), and each level is divided by its transfer. The mean transfer of the passes is kept
(a transfer common to every pass changes geometry and compliance alike and is the
inversion's business). Dividing rather than subtracting keeps a pass's own dip scaled as its
transfer scaled it. Nothing is done on smooth rail (no common signal to fit on) or where
passes overlap too little. Measured: docs/accuracy.md "Bogie vehicles"; docs/method.md §10.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.fft import irfft, next_fast_len, rfft, rfftfreq
from scipy.ndimage import maximum_filter1d, minimum_filter1d

from .detect import robust_baseline, robust_sigma
from .errors import check_settings

__all__ = ["EqualiseConfig", "Equalisation", "equalise_passes"]

_TUKEY_C = 4.685
"""Bisquare constant (95 % efficiency for normal residuals)."""


@dataclass(frozen=True)
class EqualiseConfig:
    """Settings of the per-pass transfer equalisation.

    Parameters
    ----------
    n_nodes : int
        Wavelengths (log-spaced from ``shortest_m`` to the band's longest) at which a
        pass's transfer is free: a gain and a quadrature part each, linear in
        log-wavelength between them.
    shortest_m : float
        Below this wavelength the transfer is taken as 1, reaching it linearly in
        log-wavelength at the band's shortest, m. There the vehicles' errors are small and
        the passes' common level is thin (a bogie's wheels cancel wavelengths of twice
        their spacing, 3.8-5.2 m, and every pass is seen through every bogie): a gain fitted
        there is mostly noise, and dividing by it reshapes a zone's dip.
    min_overlap_m : float
        Shortest stretch a pass must share with at least one other pass, away from the
        ends, for its transfer to be fitted, m.
    min_common_mm : float
        Smallest robust spread of the passes' mean level for which the rail counts as rough
        enough to fit on, mm.
    min_gain_error : float
        Smallest relative transfer error (fraction, largest over the nodes) that is taken
        out. The fit's own scatter is about 1-2 % (measured with vehicles exactly as
        registered), and a 1 % error of a 1 mm rail is 0.01 mm of level, a quarter of a
        zone's dip in compliance between a coach and a wagon: below it the pass is left as
        it is.
    max_gain_error : float
        Largest relative transfer error accepted (fraction); a pass fitted beyond it is left
        as it is (the fit, not the vehicle, is then suspect).
    iterations : int
        Rounds of fitting each pass against the mean of the equalised passes.
    guard_m : float
        A point the robust fit rejects takes its neighbours within this distance with it
        (a zone's dip has flanks that the bisquare alone would keep), m; also the margin
        kept around a candidate zone.
    candidate_sigma : float
        Where the passes' loads differ, a point whose load-proportional dip (the slope of
        level on load, less its 40 m baseline) stands this many robust standard deviations
        out is a candidate zone and left out of the fit (with ``guard_m`` either side).
    """

    n_nodes: int = 6
    shortest_m: float = 8.0
    min_overlap_m: float = 120.0
    min_common_mm: float = 0.2
    min_gain_error: float = 0.03
    max_gain_error: float = 0.35
    iterations: int = 3
    guard_m: float = 6.0
    candidate_sigma: float = 2.5

    def __post_init__(self) -> None:
        checks = {
            "n_nodes": self.n_nodes >= 2,
            "shortest_m": self.shortest_m > 0,
            "min_overlap_m": self.min_overlap_m > 0,
            "min_common_mm": self.min_common_mm >= 0,
            "max_gain_error": 0 <= self.min_gain_error < self.max_gain_error < 1,
            "iterations": self.iterations >= 1,
            "guard_m": self.guard_m >= 0,
            "candidate_sigma": self.candidate_sigma > 0,
        }
        check_settings(self, checks, "equalisation")


@dataclass(frozen=True)
class Equalisation:
    """What the equalisation did.

    Attributes
    ----------
    levels_mm : ndarray
        The equalised levels (passes x points), mm; NaN where not covered.
    node_wavelength_m : ndarray
        The wavelengths of the transfer's nodes, m.
    transfer : ndarray of complex
        Per pass, the fitted relative transfer at the nodes (passes x nodes); 1 where the
        pass was left as it is.
    applied : ndarray of bool
        Per pass, whether its level was equalised.
    """

    levels_mm: NDArray[np.float64]
    node_wavelength_m: NDArray[np.float64]
    transfer: NDArray[np.complex128]
    applied: NDArray[np.bool_]


def _basis(freq: NDArray[np.float64], nodes_m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Hat functions in log-wavenumber at the nodes (nodes x frequencies), flat beyond the
    end nodes; they sum to 1 everywhere."""
    u = np.log(np.maximum(freq, 1e-12))
    knots = np.log(1.0 / nodes_m[::-1])  # increasing wavenumber
    out = np.empty((nodes_m.size, freq.size))
    for b in range(nodes_m.size):
        e = np.zeros(nodes_m.size)
        e[b] = 1.0
        out[b] = np.interp(u, knots, e[::-1])
    return out


def equalise_passes(
    levels_mm: NDArray[np.float64],
    step_m: float,
    lambda_min_m: float,
    lambda_max_m: float,
    weights: NDArray[np.float64] | None = None,
    loads_n: NDArray[np.float64] | None = None,
    config: EqualiseConfig | None = None,
) -> Equalisation:
    """Fit and remove each pass's transfer relative to the passes' mean.

    Parameters
    ----------
    levels_mm : ndarray
        Levels of the passes on one grid (passes x points), mm, in the band; NaN where a
        pass does not cover a point (each pass one contiguous stretch).
    step_m : float
        Grid step, m.
    lambda_min_m, lambda_max_m : float
        The band of the levels, m.
    weights : ndarray, optional
        Relative trust in each pass's level per point (passes x points, >= 0), e.g. lower
        near a pass's ends; 1 by default.
    loads_n : ndarray, optional
        Each pass's mean (equivalent) wheel load, N: where they differ, the points where the
        level dips in proportion to the load are candidate zones, kept out of the fit.
    config : EqualiseConfig, optional

    Returns
    -------
    Equalisation
    """
    cfg = config or EqualiseConfig()
    z = np.asarray(levels_mm, dtype=float)
    n_pass, n = z.shape
    shortest = min(max(cfg.shortest_m, lambda_min_m), lambda_max_m / 2)
    nodes = np.geomspace(shortest, lambda_max_m, cfg.n_nodes)
    unit = np.ones((n_pass, cfg.n_nodes), dtype=complex)
    untouched = Equalisation(z, nodes, unit, np.zeros(n_pass, dtype=bool))
    w_in = np.ones_like(z) if weights is None else np.asarray(weights, dtype=float)
    cov = np.isfinite(z)
    shared = cov.sum(axis=0) >= 2
    if n_pass < 2 or shared.sum() * step_m < cfg.min_overlap_m:
        return untouched
    common = _shared_mean(z, shared)
    if not robust_sigma(common[shared]) >= cfg.min_common_mm:
        return untouched

    nfft = next_fast_len(2 * n)
    freq = rfftfreq(nfft, step_m)
    # a fixed node of transfer 1 at the band's shortest wavelength, when below the fitted
    with_fixed = _basis(freq, np.concatenate([[lambda_min_m], nodes]))
    phi0 = with_fixed[0] if shortest > lambda_min_m else np.zeros(freq.size)
    phi = with_fixed[1:] if shortest > lambda_min_m else _basis(freq, nodes)
    spectra = np.array([rfft(np.where(cov[j], z[j], 0.0), nfft) for j in range(n_pass)])
    coef = unit.copy()
    ok = np.zeros(n_pass, dtype=bool)
    guard = int(round(cfg.guard_m / step_m))
    for _ in range(cfg.iterations):
        eq = _apply(spectra, phi0, phi, coef, ok, cov, n, nfft)
        keep = _outside_candidates(eq, loads_n, step_m, guard, cfg.candidate_sigma)
        ref = _shared_mean(eq, shared)
        ref_spec = rfft(np.where(shared, ref, 0.0), nfft)
        # the regressors: the mean level through each node's gain and quadrature part
        cols = [irfft(p * ref_spec, nfft)[:n] for p in phi]
        cols += [irfft(-1j * p * ref_spec, nfft)[:n] for p in phi]
        X = np.array(cols).T
        fixed = irfft(phi0 * ref_spec, nfft)[:n]
        new = unit.copy()
        fitted = np.zeros(n_pass, dtype=bool)
        for j in range(n_pass):
            use = cov[j] & shared & keep & (w_in[j] > 0)
            if use.sum() * step_m < cfg.min_overlap_m:
                continue
            beta = _bisquare_fit(X[use], z[j, use] - fixed[use], w_in[j, use], guard)
            h = beta[: cfg.n_nodes] - 1j * beta[cfg.n_nodes :]
            if np.all(np.abs(h - 1.0) <= cfg.max_gain_error):
                new[j], fitted[j] = h, True
        # keep the passes' mean transfer: only the differences are the vehicles' own
        if fitted.any():
            new[fitted] /= new[fitted].mean(axis=0)
        coef, ok = new, fitted
    ok &= np.max(np.abs(coef - 1.0), axis=1) >= cfg.min_gain_error
    if not ok.any():
        return untouched
    return Equalisation(_apply(spectra, phi0, phi, coef, ok, cov, n, nfft), nodes, coef, ok)


def _shared_mean(levels: NDArray[np.float64], shared: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The passes' mean level where at least two cover a point, else 0."""
    cov = np.isfinite(levels) & shared
    total = np.where(cov, levels, 0.0).sum(axis=0)
    return np.where(shared, total / np.maximum(cov.sum(axis=0), 1), 0.0)


def _outside_candidates(
    levels: NDArray[np.float64],
    loads: NDArray[np.float64] | None,
    step_m: float,
    guard: int,
    n_sigma: float,
) -> NDArray[np.bool_]:
    """The points clear of candidate zones: where the per-point straight line of level
    against load has a slope (a softening: heavier passes lower) within ``n_sigma`` robust
    standard deviations of its 40 m baseline, and not within ``guard`` points of one that
    has not. All points when the loads do not differ."""
    n = levels.shape[1]
    if loads is None:
        return np.ones(n, dtype=bool)
    f = np.asarray(loads, dtype=float)
    cov = np.isfinite(levels) & np.isfinite(f)[:, None]
    c = cov.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        fm = np.where(cov, f[:, None], 0.0).sum(axis=0) / c
        df = np.where(cov, f[:, None] - fm, 0.0)
        zm = np.where(cov, levels, 0.0).sum(axis=0) / c
        sxx = (df**2).sum(axis=0)
        slope = -(df * np.where(cov, levels - zm, 0.0)).sum(axis=0) / sxx
    slope = np.where((c >= 2) & (sxx > 0), slope, np.nan)
    ok = np.isfinite(slope)
    if ok.sum() < 8:
        return np.ones(n, dtype=bool)
    resid = slope - robust_baseline(slope, step_m, 40.0)
    s = robust_sigma(resid[ok])
    soft = ok & (resid > n_sigma * s)
    if guard > 0:
        soft = maximum_filter1d(soft.astype(np.uint8), 2 * guard + 1, mode="nearest") > 0
    return ~soft


def _apply(
    spectra: NDArray[np.complex128],
    phi0: NDArray[np.float64],
    phi: NDArray[np.float64],
    coef: NDArray[np.complex128],
    ok: NDArray[np.bool_],
    cov: NDArray[np.bool_],
    n: int,
    nfft: int,
) -> NDArray[np.float64]:
    """Every pass's level divided by its transfer (the passes not fitted as they are)."""
    out = np.empty((spectra.shape[0], n))
    for j in range(spectra.shape[0]):
        h = phi0 + coef[j] @ phi if ok[j] else 1.0
        out[j] = irfft(spectra[j] / h, nfft)[:n]
    return np.where(cov, out, np.nan)


def _bisquare_fit(
    X: NDArray[np.float64],
    y: NDArray[np.float64],
    w: NDArray[np.float64],
    guard: int = 0,
    rounds: int = 6,
) -> NDArray[np.float64]:
    """Least squares of ``y ~ X beta`` with weights ``w`` and Tukey's bisquare on the
    residuals (iteratively reweighted, starting from the plain fit); a robust weight is the
    smallest within ``guard`` points."""
    rw = np.ones_like(y)
    beta: NDArray[np.float64] = np.zeros(X.shape[1])
    for _ in range(rounds):
        # normal equations by einsum: a few well-conditioned columns; BLAS calls on such
        # thin matrices spin threads on a busy machine for 100x the work. Weighting the rows
        # first leaves einsum a two-operand product, 2-3x faster than its three-operand loop.
        ww = w * rw
        xw = X * ww[:, None]
        gram = np.einsum("ni,nj->ij", xw, X)
        beta = np.linalg.solve(gram, np.einsum("ni,n->i", xw, y))
        r = y - np.einsum("ni,i->n", X, beta)
        s = robust_sigma(r[rw > 0])
        if not s > 0:
            break
        u = r / (_TUKEY_C * s)
        rw = np.where(np.abs(u) < 1.0, (1.0 - u**2) ** 2, 0.0)
        if guard > 0:
            rw = minimum_filter1d(rw, 2 * guard + 1, mode="nearest")
    return beta
