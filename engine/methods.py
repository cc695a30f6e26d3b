"""The inversion methods, looked up by name in :data:`METHODS` (as scipy's ``solve_ivp`` does).

Every method takes the same :class:`MethodInput` (the log, the axle positions, the chainage
grid, the vehicle and the band) and returns an :class:`Inversion`: each axle's level at every
sample (m) and on the grid, band-passed (mm), and the sensor noise it measured. A new method is
one function added to :data:`METHODS`; :func:`engine.pipeline.process_run` does the rest.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from .chainage import AxlePositions, bandpass_distance, to_grid
from .direct import direct_inverse, filtered_direct_inverse
from .errors import ParameterError
from .optimisation import windowed_least_squares
from .runlog import RunLog
from .spectral import AxleDelay, BandSpectrum, estimate_white_noise, spectral_inverse
from .vehicle import VehicleModel, VehicleParams


@dataclass(frozen=True)
class MethodInput:
    """What every method is given.

    Attributes
    ----------
    log : RunLog
        The run, SI units.
    positions : AxlePositions
        Chainage of body and axles at each sample, m.
    grid : ndarray
        Regular chainage grid of the profile, m (increasing).
    step_m : float
        Its step, m.
    vehicle : VehicleModel
        The logging vehicle.
    f_lo_hz, f_hi_hz : float
        Time-frequency band of the inversion, Hz (from :func:`engine.setup.prepare_run`).
    lambda_min_m, lambda_max_m : float
        Wavelength band of the profile, m.
    taper : float
        Relative width of the band's cosine tapers.
    """

    log: RunLog
    positions: AxlePositions
    grid: NDArray[np.float64]
    step_m: float
    vehicle: VehicleModel
    f_lo_hz: float
    f_hi_hz: float
    lambda_min_m: float
    lambda_max_m: float
    taper: float

    @cached_property
    def axle_times(self) -> NDArray[np.float64]:
        """When the front (row 0) and rear axle (row 1) pass each grid point, s from the
        first sample (NaN where the axle does not pass), shape (2, grid size)."""
        t = np.arange(self.log.n, dtype=np.float64) * self.log.dt
        return np.stack([to_grid(self.positions.front, t, self.grid),
                         to_grid(self.positions.rear, t, self.grid)])  # fmt: skip

    def bandpass(self, level_mm: NDArray[np.float64]) -> NDArray[np.float64]:
        """A level on the grid (mm) limited to the wavelength band."""
        return bandpass_distance(
            level_mm, self.step_m, self.lambda_min_m, self.lambda_max_m, self.taper
        )


@dataclass(frozen=True)
class Inversion:
    """What a method returns.

    Attributes
    ----------
    y_front, y_rear : ndarray or None
        Loaded level under each axle at every sample, m (None when the method kept them as
        ``band``).
    front_mm, rear_mm : ndarray
        The same on the grid, band-passed, mm (NaN where the axle did not pass).
    noise_accel_mps2, noise_pitch_rate_radps : float
        White-noise level of the two signals, RMS.
    band : BandSpectrum or None
        The levels' spectrum when the method worked in the frequency domain (the profile and
        the wheel forces on the grid are then evaluated from it).
    """

    y_front: NDArray[np.float64] | None
    y_rear: NDArray[np.float64] | None
    front_mm: NDArray[np.float64]
    rear_mm: NDArray[np.float64]
    noise_accel_mps2: float
    noise_pitch_rate_radps: float
    band: BandSpectrum | None = None


Inverter = Callable[[MethodInput], Inversion]
"""A method: :class:`MethodInput` in, :class:`Inversion` out."""


def _from_samples(
    m: MethodInput, y1: NDArray[np.float64], y2: NDArray[np.float64], sa: float, sg: float
) -> Inversion:
    # levels per sample (m) put on the grid per axle (mm) and band-passed
    front = m.bandpass(to_grid(m.positions.front, y1 * 1e3, m.grid))
    rear = m.bandpass(to_grid(m.positions.rear, y2 * 1e3, m.grid))
    return Inversion(y1, y2, front, rear, sa, sg)


def _noise(log: RunLog) -> tuple[float, float]:
    return (
        estimate_white_noise(log.accel_z_mps2, log.dt),
        estimate_white_noise(log.pitch_rate_radps, log.dt),
    )


def _from_band(
    m: MethodInput, *, wiener: bool = False, axle_delay: AxleDelay | None = None
) -> Inversion:
    """The spectral inversion (:func:`spectral_inverse`, its Wiener weighting when asked)."""
    log = m.log
    inv = spectral_inverse(
        log.accel_z_mps2, log.pitch_rate_radps, log.dt, m.vehicle, m.f_lo_hz, m.f_hi_hz,
        taper=m.taper, wiener=wiener, axle_delay=axle_delay,
    )  # fmt: skip
    # the levels where the axles pass the grid points, straight from the band spectrum
    # (no full-rate transform of an hour's samples), then band-passed in distance as above
    front, rear = inv.band.at_times(m.axle_times) * 1e3
    return Inversion(
        None, None, m.bandpass(front), m.bandpass(rear), inv.noise_accel, inv.noise_gyro,
        inv.band,
    )  # fmt: skip


def spectral(m: MethodInput) -> Inversion:
    """Frequency-domain inversion of the vehicle's transfer functions (the default)."""
    return _from_band(m)


SPEED_WINDOW_S = 0.5
"""Time over which the speed behind the axle delay is taken, s: a chainage column's steps
average out, a speed ramp's change over it is negligible."""


def _axle_delay(m: MethodInput, most: int = 1024) -> AxleDelay:
    """The rear axle's delay behind the front one at up to ``most`` instants: the measured
    points' spacing over the speed half-way along the delay (second-order in the speed's
    change), either way from each instant."""
    body, dt = m.positions.body, m.log.dt
    n = body.size
    pick = np.linspace(0, n - 1, min(most, n)).astype(np.intp)
    h = max(1, int(0.5 * SPEED_WINDOW_S / dt))
    lo, hi = np.clip(pick - h, 0, n - 1), np.clip(pick + h, 0, n - 1)
    t = pick.astype(np.float64) * dt
    speed = np.abs(body[hi] - body[lo]) / (np.maximum(hi - lo, 1) * dt)
    # a stop would put the delay at infinity: a tenth of the usual speed bounds it
    speed = np.maximum(speed, max(0.1 * float(np.median(speed)), 1e-3))
    spacing = np.abs(m.positions.front[pick] - m.positions.rear[pick])  # any vehicle kind
    first = spacing / speed
    ahead = spacing / np.interp(t + 0.5 * first, t, speed)
    behind = spacing / np.interp(t - 0.5 * first, t, speed)
    return AxleDelay(t, ahead, behind)


def wiener(m: MethodInput) -> Inversion:
    """The spectral inversion with each bin weighted by the log's own signal-to-noise ratio:
    the measured sensor noise against the levels' measured power spectrum (Wiener), the two
    axles tied as riding the same track at the run's own delay between them, which follows
    the speed; the default."""
    return _from_band(m, wiener=True, axle_delay=_axle_delay(m))


def _half_car(m: MethodInput, method: str) -> VehicleParams:
    """The half car of a method whose algebra is the half car's (the paper's recursion)."""
    if not isinstance(m.vehicle, VehicleParams):
        raise ParameterError(
            f"the {method} method needs a half-car vehicle, got kind {m.vehicle.kind!r} "
            "(use the spectral or least-squares method)",
            field="method",
        )
    return m.vehicle


def filtered_direct(m: MethodInput) -> Inversion:
    """Time-domain direct inversion with band-limited integration (half car only)."""
    log = m.log
    res = filtered_direct_inverse(
        log.accel_z_mps2, log.pitch_rate_radps, log.dt, _half_car(m, "filtered-direct"),
        m.f_lo_hz, m.f_hi_hz,
    )  # fmt: skip
    return _from_samples(m, res.y_front, res.y_rear, *_noise(log))


def direct(m: MethodInput) -> Inversion:
    """Time-domain direct inversion (Newmark), no band limit inside the integration (half
    car only)."""
    log = m.log
    res = direct_inverse(log.accel_z_mps2, log.pitch_rate_radps, log.dt, _half_car(m, "direct"))
    return _from_samples(m, res.y_front, res.y_rear, *_noise(log))


def least_squares(m: MethodInput) -> Inversion:
    """Windowed least-squares fit of one level on the grid seen by both axles."""
    log, pos, grid = m.log, m.positions, m.grid
    xf, xr = pos.front, pos.rear
    if pos.sign < 0:  # the fit wants increasing chainage: mirror the track
        xf, xr = -xf, -xr
    prof = windowed_least_squares(
        log.accel_z_mps2, log.pitch_rate_radps, log.dt, xf, xr,
        grid if pos.sign > 0 else -grid[::-1], m.vehicle,
    )  # fmt: skip
    prof = prof if pos.sign > 0 else prof[::-1]
    level = m.bandpass(prof)
    filled = np.where(np.isfinite(level), level, 0.0) * 1e-3
    y1, y2 = np.interp(pos.front, grid, filled), np.interp(pos.rear, grid, filled)
    return Inversion(y1, y2, level, level, *_noise(log))


METHODS: dict[str, Inverter] = {
    "wiener": wiener,
    "spectral": spectral,
    "filtered-direct": filtered_direct,
    "least-squares": least_squares,
    "direct": direct,
}
"""The inversion methods by name (the first is the default)."""
