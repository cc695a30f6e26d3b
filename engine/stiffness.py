"""Support-stiffness loss of a soft zone from its dip in the loaded profile.

A static beam-on-discrete-supports fit: the rail (EI, support spacing, nominal support
stiffness) under the average static wheel load is solved for a moving point load, with the
supports inside ``[start, end]`` softened by a fraction ``loss``. The modelled dip (loaded level
on the soft zone minus loaded level on sound track) is passed through the same wavelength band
as the measured profile, and ``start``, ``end`` and ``loss`` are adjusted until it matches.

Assumptions: quasi-static loading (dynamic amplification at 20-30 m/s is a few per cent),
no ballast or sleeper masses, a single wheel load (the other axle is several decay lengths
away), the track's nominal stiffness is right away from the zone, and the rail itself has no
irregularity there (a geometric dip of the unloaded rail would be read as softness).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.fft as sfft
from numpy.typing import NDArray
from scipy.linalg import solveh_banded

from .beam import BANDWIDTH, element_matrices, hermite_shape
from .errors import ParameterError
from .spectral import band_window
from .track import TrackParams

MAX_LOSS = 0.95
"""Largest stiffness loss the fit will report (fraction)."""

_COARSE_LOSSES = np.linspace(0.02, MAX_LOSS, 32)
"""The losses :func:`fit_zone` tries first, fraction."""

_FINE_STEPS = np.arange(9, dtype=np.float64)


def _fine_losses(lo: float, hi: float) -> NDArray[np.float64]:
    """``np.clip(np.linspace(lo, hi, 9), 0, MAX_LOSS)``, the same numbers without the
    overhead of either (the loss search runs it some ten thousand times per pass)."""
    y = _FINE_STEPS * ((hi - lo) / 8) + lo
    y[-1] = hi
    np.minimum(y, MAX_LOSS, out=y)
    return np.maximum(y, 0.0, out=y)


@dataclass(frozen=True)
class ZoneFit:
    """Result of fitting a soft zone.

    Attributes
    ----------
    start_m, end_m : float
        First and last softened support, m.
    loss : float
        Stiffness loss, fraction of nominal (0-1).
    rms_mm : float
        RMS misfit between modelled and measured dip over the fit window, mm.
    """

    start_m: float
    end_m: float
    loss: float
    rms_mm: float


class QuasiStaticModel:
    """Loaded level under a moving static point load on a local stretch of discrete supports.

    Parameters
    ----------
    params : TrackParams
        Rail and nominal support properties.
    x0, x1 : float
        Chainage range of interest, m; the beam modelled extends 20 m beyond both ends.
    grid : ndarray
        Chainages (m) where the loaded level is evaluated (within ``[x0, x1]``).
    load : float
        Wheel load, N.
    """

    def __init__(
        self, params: TrackParams, x0: float, x1: float, grid: NDArray[np.float64], load: float
    ) -> None:
        s = params.spacing
        first = int(np.floor((x0 - 20.0) / s))
        last = int(np.ceil((x1 + 20.0) / s))
        self.params = params
        self.node_x = np.arange(first, last + 1) * s
        n_nodes = self.node_x.size
        self.n_dof = 2 * n_nodes
        Ke, _ = element_matrices(params.EI, 1.0, s)
        band = np.zeros((BANDWIDTH + 1, self.n_dof))
        for a in range(4):
            for b in range(a, 4):
                band[BANDWIDTH + a - b, 2 * np.arange(n_nodes - 1) + b] += Ke[a, b]
        self.band_beam = band
        self.grid = grid
        e = np.clip(np.floor((grid - self.node_x[0]) / s).astype(int), 0, n_nodes - 2)
        xi = (grid - self.node_x[0]) / s - e
        self.first_dof = 2 * e
        self.shape = hermite_shape(xi, s)
        self.rhs = np.zeros((self.n_dof, grid.size))
        cols = np.arange(grid.size)
        for j in range(4):
            self.rhs[self.first_dof + j, cols] = self.shape[:, j]
        self.load = load

    def level(self, k_factor: NDArray[np.float64]) -> NDArray[np.float64]:
        """Loaded level under the load at each grid point, m (negative = down).

        ``k_factor`` multiplies the nominal stiffness of each modelled support.
        """
        band = self.band_beam.copy()
        band[BANDWIDTH, 0::2] += self.params.k_nominal * k_factor
        W = solveh_banded(band, self.rhs, lower=False, check_finite=False)
        return -self.load * self._at_load(W)

    def factors(self, start_m: float, end_m: float, loss: float) -> NDArray[np.float64]:
        """Stiffness factor of each modelled support for a zone (inclusive bounds, m)."""
        f = np.ones(self.node_x.size)
        tol = 1e-6
        f[(self.node_x >= start_m - tol) & (self.node_x <= end_m + tol)] = 1.0 - loss
        return f

    def _at_load(self, W: NDArray[np.float64]) -> NDArray[np.float64]:
        cols = np.arange(self.grid.size)
        defl = np.zeros(self.grid.size)
        for j in range(4):
            defl += self.shape[:, j] * W[self.first_dof + j, cols]
        return defl


@lru_cache(maxsize=16)
def _influence_nodal(params: TrackParams, half_nodes: int) -> NDArray[np.float64]:
    """Nodal displacements of a long uniform rail under a unit load on its middle support."""
    s = params.spacing
    n_nodes = 2 * half_nodes + 1
    n_dof = 2 * n_nodes
    Ke, _ = element_matrices(params.EI, 1.0, s)
    band = np.zeros((BANDWIDTH + 1, n_dof))
    for a in range(4):
        for b in range(a, 4):
            band[BANDWIDTH + a - b, 2 * np.arange(n_nodes - 1) + b] += Ke[a, b]
    band[BANDWIDTH, 0::2] += params.k_nominal
    rhs = np.zeros(n_dof)
    rhs[2 * half_nodes] = 1.0
    return solveh_banded(band, rhs, lower=False, check_finite=False)


class InfluenceLine:
    """Deflection of a support of the nominal (uniform) rail under a unit load at offset r.

    By reciprocity this is also the deflection at offset ``r`` (m) from a support under a
    unit load on that support, m/N: one banded solve, evaluated anywhere exactly with the
    Hermite shape functions. Zero beyond ``reach_m`` (the response has decayed to ~1e-12).
    """

    def __init__(self, params: TrackParams, reach_m: float = 30.0) -> None:
        self.params = params
        self.half = int(np.ceil(reach_m / params.spacing))
        self.nodal = _influence_nodal(params, self.half)
        self.reach = self.half * params.spacing

    def __call__(self, r: NDArray[np.float64]) -> NDArray[np.float64]:
        s = self.params.spacing
        ra = np.asarray(r, dtype=float)
        u = ra / s + self.half
        e = np.clip(np.floor(u).astype(np.intp), 0, 2 * self.half - 1)
        sh = hermite_shape(u - e, s)
        out = np.zeros(ra.shape)
        for j in range(4):
            out += sh[..., j] * self.nodal[2 * e + j]
        out[np.abs(ra) >= self.reach] = 0.0
        return out


def _bandpass_rows(
    y: NDArray[np.float64], step_m: float, lambda_min: float, lambda_max: float, taper: float
) -> NDArray[np.float64]:
    """:func:`engine.chainage.bandpass_distance` for the rows of a NaN-free 2-D array."""
    n = y.shape[-1]
    pad = min(n - 1, int(np.ceil(lambda_max * (1 + taper) / step_m)))
    ext = np.concatenate([y[:, pad:0:-1], y, y[:, -2 : -pad - 2 : -1]], axis=1)
    ext = ext - ext.mean(axis=1, keepdims=True)
    nfft = sfft.next_fast_len(ext.shape[1], real=True)
    F = sfft.rfft(ext, nfft, axis=1)
    F *= band_window(sfft.rfftfreq(nfft, step_m), 1.0 / lambda_max, 1.0 / lambda_min, taper)
    return sfft.irfft(F, nfft, axis=1)[:, pad : pad + n]


@lru_cache(maxsize=64)
def _bandpass_kernel(
    n: int, step_m: float, lambda_min: float, lambda_max: float, taper: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """What :func:`_bandpass_rows` does to rows of length ``n``, as a circular convolution.

    The rows are mirrored by ``pad`` points either side, their mean removed, zero-padded to
    ``nfft`` and weighted by the band window: each output point ``q`` (padded index) is
    ``sum_p h[q - p] (ext_p - mean)``, ``h`` the window's impulse response. Returns ``h``,
    ``S[q] = sum_{p < L} h[q - p]`` (what the mean removal takes away per unit mean, ``L`` the
    mirrored length) and ``pad``; a few kB, where the matrix itself is ``n²`` floats.
    """
    pad = min(n - 1, int(np.ceil(lambda_max * (1 + taper) / step_m)))
    length = n + 2 * pad
    nfft = sfft.next_fast_len(length, real=True)
    h = sfft.irfft(
        band_window(sfft.rfftfreq(nfft, step_m), 1.0 / lambda_max, 1.0 / lambda_min, taper), nfft
    )
    box = np.zeros(nfft)
    box[:length] = 1.0
    S = sfft.irfft(sfft.rfft(h) * sfft.rfft(box), nfft)
    return h, S, pad


def _bandpass_block(
    n: int,
    step_m: float,
    lambda_min: float,
    lambda_max: float,
    taper: float,
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
) -> NDArray[np.float64]:
    """Rows ``rows`` and columns ``cols`` of the linear map of :func:`_bandpass_rows` on rows
    of length ``n`` (``y @ M`` band-passes ``y``): ``M[rows][:, cols]``, from the map's
    convolution kernel (:func:`_bandpass_kernel`) instead of band-passing ``n`` unit rows.

    Input point ``i`` stands in the mirrored row at ``pad + i`` and, near the ends, at
    ``pad - i`` (``1 <= i <= pad``) and ``pad + 2 n - 2 - i`` (``i >= n - 1 - pad``).
    """
    h, S, pad = _bandpass_kernel(n, step_m, lambda_min, lambda_max, taper)
    r = np.asarray(rows, dtype=np.intp)
    c = np.asarray(cols, dtype=np.intp)[None, :]
    # offsets within (-nfft, nfft): a negative one indexes h circularly as it should
    out = h[c - r[:, None]]
    count = np.ones(r.size)
    left = (r >= 1) & (r <= pad)
    if left.any():
        out[left] += h[c + r[left, None]]
        count[left] += 1.0
    right = (r >= n - 1 - pad) & (r <= n - 2)
    if right.any():
        out[right] += h[c - 2 * n + 2 + r[right, None]]
        count[right] += 1.0
    out -= (count / (n + 2 * pad))[:, None] * S[pad + c]
    return out


def softening_modes(
    flexibility: NDArray[np.float64],
    influence: NDArray[np.float64],
    columns: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The modes of softening a set of supports together, for :func:`modal_dips`.

    Parameters
    ----------
    flexibility : ndarray
        ``F_ij = f(x_i - x_j)`` of the ``p`` supports, m/N (symmetric).
    influence : ndarray
        ``b_j(x) = f(x - x_j)`` of each support at the profile's points, m/N, shape (p, g).
    columns : ndarray
        Linear map of a profile to what is compared (the band-pass at the fitted points),
        shape (g, w).

    Returns
    -------
    lam : ndarray
        Eigenvalues of ``F``, m/N, shape (p,).
    E : ndarray
        Each mode's squared influence mapped by ``columns``, (m/N)², shape (p, w).
    """
    if flexibility.shape[0] == 0:
        return np.zeros(0), np.zeros((0, columns.shape[1]))
    lam, Q = np.linalg.eigh(flexibility)
    C = Q.T @ influence
    return lam, (C * C) @ columns


def modal_dips(
    lam: NDArray[np.float64],
    E: NDArray[np.float64],
    losses: NDArray[np.float64],
    k_nominal: float,
    load: float,
) -> NDArray[np.float64]:
    """Change of the loaded level when the supports of :func:`softening_modes` lose
    ``losses`` (fractions, 0..1) of their stiffness ``k_nominal`` (N/m) under a static
    ``load`` (N): mm, positive up (a softened zone sinks: negative), one row per loss.

    Softening by ``D = d I`` (``d = -loss k_nominal``) changes the level by
    ``P b^T (D^-1 + F)^-1 b``; with ``F = Q diag(lam) Q^T`` that is
    ``P sum_k d / (1 + lam_k d) (Q^T b)_k^2``: a weighted sum of the modes, one small product
    per loss instead of a matrix inverse, and finite at loss 0.
    """
    d = -np.asarray(losses, dtype=float)[:, None] * k_nominal
    # n^T K^-1 n - n^T K0^-1 n = -b^T (D^-1 + F)^-1 b; the level is -P times that
    return ((d / (1.0 + lam[None, :] * d)) @ E) * (load * 1e3)


def fit_zone(
    grid: NDArray[np.float64],
    residual_mm: NDArray[np.float64],
    start_m: float,
    end_m: float,
    params: TrackParams,
    load: float,
    lambda_min: float,
    lambda_max: float,
    *,
    taper: float = 0.3,
    refine_extent: bool = True,
    wheel_offsets_m: tuple[float, ...] = (0.0,),
    wheel_sets: tuple[tuple[tuple[float, ...], float], ...] | None = None,
    trend_order: int | None = None,
) -> ZoneFit:
    """Fit start, end and stiffness loss of one soft zone to the measured profile.

    Parameters
    ----------
    grid : ndarray
        Regular chainage grid of the profile, m, increasing.
    residual_mm : ndarray
        Measured loaded level minus its baseline on ``grid``, mm.
    start_m, end_m : float
        First guess of the zone's extent, m.
    params : TrackParams
        Nominal rail and support properties.
    load : float
        Static load of each wheel of the measured point, N.
    lambda_min, lambda_max : float
        Wavelength band the measured profile was limited to, m.
    taper : float
        Relative width of that band's edges.
    refine_extent : bool
        Also move the zone's ends (support by support); otherwise only the loss is fitted.
    wheel_offsets_m : tuple of float
        The wheels of the measured point relative to it, m: ``(0,)`` for a half car's axle,
        ``(+a/2, -a/2)`` for a bogie of wheelbase ``a``. Each carries ``load``; the profile
        is the mean of the rail levels under them, each the superposition of every wheel's
        deflection basin.
    wheel_sets : tuple of (offsets, load), optional
        Instead of ``wheel_offsets_m`` and ``load``: several sets of wheels, each with the
        load of each of its wheels (N; negative subtracts); the modelled dip is the sum of
        the sets' dips. The separation's compliance dip is such a blend of its passes'
        wheels.
    trend_order : int, optional
        Also fit a polynomial of this order over the fitted window (a nuisance term: the
        misfit is taken after projecting it out of the measured-minus-modelled residual).
        For profiles whose noise is mostly long-wave, where a slope across the zone would
        otherwise be read as a longer or shorter zone. None: no trend (the default).

    Notes
    -----
    Softening the supports ``j`` in the zone by ``D = -loss k_nominal`` is a low-rank change
    of the nominal stiffness matrix ``K0``, so the loaded level changes by
    ``P b(x)^T (D^-1 I + F)^-1 b(x)`` with ``b_j(x) = f(x - x_j)`` and ``F_ij = f(x_i - x_j)``,
    ``f`` the nominal influence line (:class:`InfluenceLine`), evaluated in the eigenbasis
    of ``F`` (:func:`modal_dips`). Losses are scanned in batches.

    With ``n`` wheels at ``x + o_k``, each of load ``P``, the mean level under them changes
    by ``(1/n) sum_m sum_k P b(x + o_m)^T (...) b(x + o_k) = (P/n) s^T (...) s`` with
    ``s(x) = sum_k b(x + o_k)``: the single-load formula with ``b`` replaced by ``s`` and the
    load by ``P/n``.
    """
    sets = [(np.asarray(o, dtype=float), float(w))
            for o, w in (wheel_sets or ((wheel_offsets_m, load),))]  # fmt: skip
    for offsets, _ in sets:
        if offsets.ndim != 1 or offsets.size == 0 or not np.all(np.isfinite(offsets)):
            raise ParameterError(
                f"wheel_offsets_m must be one or more finite offsets, m, got {offsets.tolist()!r}",
                field="wheel_offsets_m",
            )
    reach = max(float(np.max(np.abs(o))) for o, _ in sets)
    step = float(grid[1] - grid[0])
    s = params.spacing
    span = lambda_max * (1 + taper) + 5.0
    lo, hi = start_m - span, end_m + span
    i0 = max(0, int(np.searchsorted(grid, lo)))
    i1 = min(grid.size, int(np.searchsorted(grid, hi)) + 1)
    g = grid[i0:i1]
    meas = residual_mm[i0:i1]
    ok = np.isfinite(meas)
    if ok.sum() < 8:
        return ZoneFit(start_m, end_m, 0.0, float("nan"))
    infl = InfluenceLine(params)
    # candidate supports: the first guess widened by a few spacings
    j0 = int(np.floor((start_m - 6 * s) / s))
    j1 = int(np.ceil((end_m + 6 * s) / s))
    sup_x = np.arange(j0, j1 + 1) * s
    # the change of level is b^T (...) b with b the influence of the candidate supports:
    # it has decayed to ~1e-7 of its peak 12 m away (exp(-beta x), beta ~ 1.3 /m)
    near = (g >= sup_x[0] - 12.0 - reach) & (g <= sup_x[-1] + 12.0 + reach)
    Bs = []  # per set (m, g near): its wheels' summed influence
    for offsets, _ in sets:
        B = np.zeros((sup_x.size, int(near.sum())))
        for o in offsets:
            B += infl(g[near][None, :] + o - sup_x[:, None])
        Bs.append(B)
    Fss = infl(sup_x[None, :] - sup_x[:, None])
    fit_w = ok & (
        np.abs(g - 0.5 * (start_m + end_m)) <= 0.5 * (end_m - start_m) + 2 * lambda_min + 2
    )
    kn = params.k_nominal
    # the band-pass is linear: only its rows near the zone and its fitted columns are needed
    bp_fit = _bandpass_block(
        g.size, step, lambda_min, lambda_max, taper, np.flatnonzero(near), np.flatnonzero(fit_w)
    )
    meas_fit = meas[fit_w]
    trend = None  # orthonormal columns spanning the trend over the fitted window
    if trend_order is not None:
        u = g[fit_w] - g[fit_w].mean()
        trend = np.linalg.qr(np.vander(u / max(float(np.ptp(u)), step), trend_order + 1))[0]

    def modes(a: float, b: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        pick = np.flatnonzero((sup_x >= a - 1e-6) & (sup_x <= b + 1e-6))
        # the zone's supports are consecutive: slices, not copies
        on = slice(int(pick[0]), int(pick[-1]) + 1) if pick.size else slice(0, 0)
        # the dip is linear in each set's squared modal influence (modal_dips): weight them
        E = None
        for (offsets, w), B in zip(sets, Bs, strict=True):
            lam, E_k = softening_modes(Fss[on, on], B[on], bp_fit)
            E = E_k * (w / offsets.size) if E is None else E + E_k * (w / offsets.size)
        assert E is not None
        return lam, E

    tried: dict[tuple[float, float], tuple[float, float]] = {}

    def best_loss(a: float, b: float) -> tuple[float, float]:
        # the extent search below revisits its neighbours' extents: each is fitted once
        key = (round(a / s), round(b / s))
        if key not in tried:
            tried[key] = _best_loss(a, b)
        return tried[key]

    n_fit = meas_fit.size

    def misfit(
        lam: NDArray[np.float64], E: NDArray[np.float64], losses: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """RMS misfit of the band-passed modelled dips (one per loss) at the fitted columns."""
        d = modal_dips(lam, E, losses, kn, 1.0)
        d -= meas_fit
        if trend is not None:
            d -= (d @ trend) @ trend.T
        d *= d
        return np.sqrt(d.sum(axis=1) / n_fit)

    def _best_loss(a: float, b: float) -> tuple[float, float]:
        lam, E = modes(a, b)
        losses = _COARSE_LOSSES
        for _ in range(2):
            err = misfit(lam, E, losses)
            k = int(err.argmin())
            best_l, best_e = float(losses[k]), float(err[k])
            width = losses[1] - losses[0]
            losses = _fine_losses(best_l - width, best_l + width)
        if 0 < k < err.size - 1:
            # vertex of the parabola through the best point and its neighbours
            e0, e1, e2 = err[k - 1] ** 2, err[k] ** 2, err[k + 1] ** 2
            den = e0 - 2 * e1 + e2
            if den > 0:
                h = losses[1] - losses[0]
                best_l = min(max(float(best_l + 0.5 * h * (e0 - e2) / den), 0.0), MAX_LOSS)
        return best_l, best_e

    a = np.ceil(start_m / s - 1e-9) * s
    b = np.floor(end_m / s + 1e-9) * s
    if b < a:
        a = b = round(0.5 * (start_m + end_m) / s) * s
    loss, err = best_loss(a, b)
    if refine_extent:
        for _ in range(12):
            best = (err, a, b, loss)
            for da, db in ((-s, 0.0), (s, 0.0), (0.0, -s), (0.0, s), (-s, s), (s, -s)):
                na, nb = a + da, b + db
                if nb < na or na < sup_x[0] or nb > sup_x[-1]:
                    continue
                nl, ne = best_loss(na, nb)
                if ne < best[0] - 1e-6:
                    best = (ne, na, nb, nl)
            if best[1] == a and best[2] == b:
                break
            err, a, b, loss = best
    return ZoneFit(float(a), float(b), float(loss), float(err))
