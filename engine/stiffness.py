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

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import solveh_banded

from .beam import BANDWIDTH, element_matrices, hermite_shape
from .chainage import bandpass_distance
from .track import TrackParams

MAX_LOSS = 0.95
"""Largest stiffness loss the fit will report (fraction)."""


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

    def _at_load(self, W: NDArray[np.float64]) -> NDArray[np.float64]:
        cols = np.arange(self.grid.size)
        defl = np.zeros(self.grid.size)
        for j in range(4):
            defl += self.shape[:, j] * W[self.first_dof + j, cols]
        return defl

    def prepare_zone_updates(self, x_min: float, x_max: float) -> None:
        """Precompute what :meth:`zone_level` needs for zones within ``[x_min, x_max]`` m.

        Softening ``m`` supports is a rank-``m`` change of the nominal stiffness matrix, so
        the loaded level of any zone follows from the nominal solution by a Woodbury update.
        """
        band = self.band_beam.copy()
        band[BANDWIDTH, 0::2] += self.params.k_nominal
        self._W0 = solveh_banded(band, self.rhs, lower=False, check_finite=False)
        self._ref = self._at_load(self._W0)
        sup = np.flatnonzero((self.node_x >= x_min - 1e-6) & (self.node_x <= x_max + 1e-6))
        self._sup = sup
        E = np.zeros((self.n_dof, sup.size))
        E[2 * sup, np.arange(sup.size)] = 1.0
        K0E = solveh_banded(band, E, lower=False, check_finite=False)
        self._EtK0E = K0E[2 * sup, :]  # (m, m)
        cols = np.arange(self.grid.size)
        # E^T K0^-1 n(x) for every grid point: the deflection at support j due to load at x
        self._EtW0 = self._W0[2 * sup, :][:, cols]

    def zone_dip(self, start_m: float, end_m: float, loss: float) -> NDArray[np.float64]:
        """Loaded level on a soft zone minus that on sound track, m (negative = deeper).

        Needs :meth:`prepare_zone_updates` over a range containing the zone.
        """
        xs = self.node_x[self._sup]
        pick = np.flatnonzero((xs >= start_m - 1e-6) & (xs <= end_m + 1e-6))
        if pick.size == 0 or loss <= 0:
            return np.zeros(self.grid.size)
        d = -loss * self.params.k_nominal
        B = self._EtW0[pick]  # (m, g)
        Kinv = np.linalg.inv(np.eye(pick.size) / d + self._EtK0E[np.ix_(pick, pick)])
        corr = np.einsum("ig,ij,jg->g", B, Kinv, B)
        # n^T K^-1 n = n^T K0^-1 n - B^T (D^-1 + E^T K0^-1 E)^-1 B
        return self.load * corr


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
    refine_extent: bool = True,
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
        Static wheel load the profile corresponds to, N.
    lambda_min, lambda_max : float
        Wavelength band the measured profile was limited to, m.
    refine_extent : bool
        Also move the zone's ends (sleeper by sleeper); otherwise only the loss is fitted.
    """
    step = float(grid[1] - grid[0])
    s = params.spacing
    lo = start_m - max(lambda_max, 15.0)
    hi = end_m + max(lambda_max, 15.0)
    sel = (grid >= lo) & (grid <= hi) & np.isfinite(residual_mm)
    if sel.sum() < 8:
        return ZoneFit(start_m, end_m, 0.0, float("nan"))
    g = grid[sel]
    meas = residual_mm[sel]
    # model on a wider window so that the band-pass sees the same surroundings
    pad = 2 * lambda_max
    wide = np.arange(g[0] - pad, g[-1] + pad + step / 2, step)
    model = QuasiStaticModel(params, wide[0], wide[-1], wide, load)
    model.prepare_zone_updates(start_m - 8 * s, end_m + 8 * s)
    inner = slice(int(round(pad / step)), int(round(pad / step)) + g.size)
    fit_w = np.abs(g - 0.5 * (start_m + end_m)) <= 0.5 * (end_m - start_m) + 2 * lambda_min + 2.0

    def dip(a: float, b: float, loss: float) -> NDArray[np.float64]:
        y = model.zone_dip(a, b, loss)
        yb = bandpass_distance(y * 1e3, step, lambda_min, lambda_max)
        return yb[inner]

    def misfit(a: float, b: float, loss: float) -> float:
        d = dip(a, b, loss) - meas
        return float(np.sqrt(np.mean(d[fit_w] ** 2)))

    def best_loss(a: float, b: float) -> tuple[float, float]:
        # the dip grows monotonically with the loss: golden-section search on [0, MAX_LOSS]
        lo_, hi_ = 0.0, MAX_LOSS
        gr = (np.sqrt(5) - 1) / 2
        c = hi_ - gr * (hi_ - lo_)
        d = lo_ + gr * (hi_ - lo_)
        fc, fd = misfit(a, b, c), misfit(a, b, d)
        for _ in range(13):
            if fc < fd:
                hi_, d, fd = d, c, fc
                c = hi_ - gr * (hi_ - lo_)
                fc = misfit(a, b, c)
            else:
                lo_, c, fc = c, d, fd
                d = lo_ + gr * (hi_ - lo_)
                fd = misfit(a, b, d)
        loss = 0.5 * (lo_ + hi_)
        return loss, misfit(a, b, loss)

    # snap to supports
    a = np.ceil(start_m / s - 1e-9) * s
    b = np.floor(end_m / s + 1e-9) * s
    if b < a:
        a = b = round(0.5 * (start_m + end_m) / s) * s
    loss, err = best_loss(a, b)
    if refine_extent:
        improved = True
        it = 0
        while improved and it < 12:
            improved = False
            it += 1
            for da, db in ((-s, 0.0), (s, 0.0), (0.0, -s), (0.0, s), (-s, s), (s, -s)):
                na, nb = a + da, b + db
                if nb < na:
                    continue
                nl, ne = best_loss(na, nb)
                if ne < err - 1e-6:
                    a, b, loss, err = na, nb, nl, ne
                    improved = True
    return ZoneFit(float(a), float(b), float(loss), err)
