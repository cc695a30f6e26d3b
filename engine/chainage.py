"""Mapping time series to track chainage and resampling onto a regular grid."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft
from numpy.typing import NDArray

from .errors import InversionError
from .runlog import RunLog
from .spectral import band_window
from .vehicle import VehicleModel

GRID_STEP_M = 0.25
"""The product's chainage grid step, m: profiles are resampled to it (the finest allowed), the
track grid of aligned runs is its multiples, and heatmap bins are never narrower."""

PRODUCT_BAND_M = (3.0, 40.0)
"""The product's wavelength band, m (shortest, longest): the default of every profile, of the
calibration's comparison and of the command line."""


@dataclass(frozen=True)
class AxlePositions:
    """Chainage of the body centre and of each axle at every sample, m."""

    body: NDArray[np.float64]
    front: NDArray[np.float64]
    rear: NDArray[np.float64]
    sign: float


def axle_positions(
    log: RunLog, vehicle: VehicleModel, start_chainage_m: float | None, direction: str
) -> AxlePositions:
    """Chainage of body centre and axles at each sample.

    Parameters
    ----------
    log : RunLog
        The run; its chainage column is used if present, otherwise its speed is integrated.
    vehicle : VehicleModel
        Gives the axle distances ``d1`` (front, ahead) and ``d2`` (rear, behind), m.
    start_chainage_m : float or None
        Chainage of the body centre at the first sample, m (required without a chainage
        column; with one, it shifts the column so that its first value is this).
    direction : {"increasing", "decreasing"}
        Direction of travel.
    """
    if direction not in ("increasing", "decreasing"):
        raise InversionError(f"direction must be 'increasing' or 'decreasing', got {direction!r}")
    sign = 1.0 if direction == "increasing" else -1.0
    if log.chainage_m is not None:
        body = log.chainage_m.astype(float, copy=True)
        if start_chainage_m is not None:
            body += start_chainage_m - body[0]
        step = np.diff(body) * sign
        if np.any(step <= 0):
            i = int(np.flatnonzero(step <= 0)[0])
            raise InversionError(
                f"chainage column must move steadily {direction}: sample {i + 1} "
                f"({body[i + 1]} m) does not follow sample {i} ({body[i]} m)"
            )
    else:
        if start_chainage_m is None:
            raise InversionError("start_chainage_m is required when the log has no chainage")
        v = log.speed()
        if np.any(v <= 0):
            i = int(np.flatnonzero(v <= 0)[0])
            raise InversionError(f"speed must be > 0 m/s; sample {i} is {v[i]} m/s")
        body = start_chainage_m + sign * log.distance()
    return AxlePositions(
        body=body, front=body + sign * vehicle.d1, rear=body - sign * vehicle.d2, sign=sign
    )


def axle_grid(
    front: NDArray[np.float64], rear: NDArray[np.float64], step_m: float = GRID_STEP_M
) -> NDArray[np.float64]:
    """The chainage grid of a run's profile: the multiples of ``step_m`` (m) from the first at
    or beyond the lowest chainage either axle reached (``front``, ``rear``, m) to the highest.

    Multiples of the step, so that every run of a track lies on one grid.
    """
    lo = min(float(front.min()), float(rear.min()))
    hi = max(float(front.max()), float(rear.max()))
    return np.arange(np.ceil(lo / step_m) * step_m, hi + 1e-9, step_m)


def to_grid(
    x: NDArray[np.float64], y: NDArray[np.float64], grid: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Linear interpolation of samples ``y`` at chainages ``x`` onto ``grid`` (NaN outside)."""
    if x[0] > x[-1]:
        x, y = x[::-1], y[::-1]
    out = np.interp(grid, x, y, left=np.nan, right=np.nan)
    return out


def bandpass_distance(
    y: NDArray[np.float64], step_m: float, lambda_min: float, lambda_max: float, taper: float = 0.3
) -> NDArray[np.float64]:
    """Zero-phase band-pass of a profile sampled every ``step_m`` metres.

    Keeps wavelengths ``lambda_min..lambda_max`` (m) with raised-cosine edges; NaN runs at
    the ends are preserved; the valid part is reflected at its ends against edge effects.
    """
    ok = np.isfinite(y)
    out = np.full_like(y, np.nan)
    if ok.sum() < 8:
        return out
    i0, i1 = int(np.argmax(ok)), int(y.size - np.argmax(ok[::-1]))
    seg = y[i0:i1]
    if not np.all(np.isfinite(seg)):
        seg = np.interp(
            np.arange(seg.size), np.flatnonzero(np.isfinite(seg)), seg[np.isfinite(seg)]
        )
    n = seg.size
    pad = min(n - 1, int(np.ceil(lambda_max * (1 + taper) / step_m)))
    ext = np.concatenate([seg[pad:0:-1], seg, seg[-2 : -pad - 2 : -1]]) if pad > 0 else seg
    ext = ext - ext.mean()
    nfft = sfft.next_fast_len(ext.size, real=True)
    F = sfft.rfft(ext, nfft)
    k = sfft.rfftfreq(nfft, step_m)
    F *= band_window(k, 1.0 / lambda_max, 1.0 / lambda_min, taper)
    out[i0:i1] = sfft.irfft(F, nfft)[pad : pad + n]
    return out
