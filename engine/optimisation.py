"""Optimisation baseline: fit the profile so that the simulated vehicle matches the log.

This is the approach the paper's direct integration replaced (there a cross-entropy search;
here the best case of it: the vehicle is linear, so the fit over each window is an exact
regularised linear least-squares problem). It is kept to measure the paper's claim that the
direct method gives the profile "in a fraction of the computing time".
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.signal import cont2discrete

from .vehicle import VehicleModel


def _discrete_vehicle(
    vehicle: VehicleModel, dt: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Bilinear (Newmark average-acceleration) discretisation of the vehicle (any kind).

    State ``[q, q']`` (2n), input ``[y1, y2]`` (m, the levels under the two measured
    points), output ``[a (m/s²), pitch rate (rad/s)]`` with ``a`` the body acceleration at
    the accelerometer.
    """
    M, C, K = vehicle.matrices()
    n = M.shape[0]
    Minv = np.linalg.inv(M)
    F = vehicle.axle_input()
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    B = np.vstack([np.zeros((n, 2)), Minv @ F])
    # measured acceleration: at the accelerometer, sensor_x_m ahead of the CG
    x = vehicle.sensor_x_m
    Cout = np.vstack([A[n] + x * A[n + 1], np.eye(2 * n)[n + 1]])
    Dout = np.vstack([B[n] + x * B[n + 1], np.zeros(2)])
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, Cout, Dout), dt, method="bilinear")
    return Ad, Bd, Cd, Dd


def windowed_least_squares(
    accel: NDArray[np.float64],
    pitch_rate: NDArray[np.float64],
    dt: float,
    x_front: NDArray[np.float64],
    x_rear: NDArray[np.float64],
    grid: NDArray[np.float64],
    vehicle: VehicleModel,
    *,
    window_s: float = 4.0,
    smoothing: float = 1e-3,
) -> NDArray[np.float64]:
    """Profile on ``grid`` fitted window by window to the measured response.

    Parameters
    ----------
    accel, pitch_rate : ndarray
        Measured body acceleration (m/s²) and pitch rate (rad/s).
    dt : float
        Sample step, s.
    x_front, x_rear : ndarray
        Chainage of each axle at each sample, m (increasing).
    grid : ndarray
        Regular chainage grid of the profile, m.
    vehicle : VehicleModel
        Any vehicle kind.
    window_s : float
        Length of each fitted window, s; windows overlap by half and the middle half is kept.
    smoothing : float
        Weight of the second-difference penalty on the profile (Tikhonov), relative.

    Returns
    -------
    ndarray
        Level on ``grid``, mm (NaN where no window reached). A constant and a slope per
        window are not observable (the vehicle rides them rigidly): consecutive windows are
        lined up on their overlap, and the caller band-passes the result.
    """
    from scipy.signal import lfilter, ss2tf

    Ad, Bd, Cd, Dd = _discrete_vehicle(vehicle, dt)
    n = accel.size
    W = min(n, max(64, int(round(window_s / dt))))
    hop = W // 2
    tfs = {}
    for i in range(2):
        for j in range(2):
            num, den = ss2tf(Ad, Bd[:, j : j + 1], Cd[i : i + 1], Dd[i : i + 1, j : j + 1])
            tfs[i, j] = (num[0], den)
    Obs = np.zeros((2 * W, 8))
    Ak = np.eye(8)
    for k in range(W):
        Obs[k] = Cd[0] @ Ak
        Obs[W + k] = Cd[1] @ Ak
        Ak = Ad @ Ak
    sa = np.std(np.diff(accel)) / np.sqrt(2) + 1e-12
    sq = np.std(np.diff(pitch_rate)) / np.sqrt(2) + 1e-12
    wrow = np.concatenate([np.full(W, 1.0 / sa), np.full(W, 1.0 / sq)])
    step = float(grid[1] - grid[0])
    out = np.full(grid.size, np.nan)
    start = 0
    while True:
        stop = min(n, start + W)
        start = stop - W
        xs1, xs2 = x_front[start:stop], x_rear[start:stop]
        g0 = max(0, int(np.floor((min(xs1.min(), xs2.min()) - grid[0]) / step)))
        g1 = min(grid.size - 1, int(np.ceil((max(xs1.max(), xs2.max()) - grid[0]) / step)) + 1)
        m = g1 - g0 + 1
        Sj = []
        for xs in (xs1, xs2):
            S = np.zeros((W, m))
            u = (xs - grid[g0]) / step
            k = np.clip(np.floor(u).astype(int), 0, m - 2)
            f = u - k
            S[np.arange(W), k] += 1 - f
            S[np.arange(W), k + 1] += f
            Sj.append(S)
        R = np.zeros((2 * W, m))
        for i in range(2):
            for j in range(2):
                b, a = tfs[i, j]
                R[i * W : (i + 1) * W] += lfilter(b, a, Sj[j], axis=0)
        bias = np.zeros((2 * W, 2))
        bias[:W, 0] = 1.0
        bias[W:, 1] = 1.0
        Amat = np.hstack([R, Obs, bias]) * wrow[:, None]
        rhs = np.concatenate([accel[start:stop], pitch_rate[start:stop]]) * wrow
        D2 = np.zeros((m - 2, Amat.shape[1]))
        ii = np.arange(m - 2)
        D2[ii, ii], D2[ii, ii + 1], D2[ii, ii + 2] = 1.0, -2.0, 1.0
        lam = smoothing * np.linalg.norm(Amat[:, :m]) / np.sqrt(m)
        sol = np.linalg.lstsq(
            np.vstack([Amat, lam * D2]), np.concatenate([rhs, np.zeros(m - 2)]), rcond=None
        )[0]
        prof = sol[:m] * 1e3
        gx = grid[g0 : g1 + 1]
        seg = out[g0 : g1 + 1]
        prev = np.isfinite(seg)
        if prev.sum() >= 4:
            # line the window up (offset and slope) with the part already fitted
            coef = np.polyfit(gx[prev], seg[prev] - prof[prev], 1)
            prof += np.polyval(coef, gx)
        # keep the middle of the window: its ends are poorly determined
        lo = gx[0] + 0.25 * (gx[-1] - gx[0]) if start > 0 else gx[0]
        hi = gx[0] + 0.75 * (gx[-1] - gx[0]) if stop < n else gx[-1]
        sel = (gx >= lo) & (gx <= hi)
        keep_old = prev & (gx < lo)
        seg[sel & ~keep_old] = prof[sel & ~keep_old]
        if stop >= n:
            break
        start += hop
    return out
