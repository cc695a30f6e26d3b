"""Sensor model: turns clean simulated signals into the log an IMU would write."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .errors import ParameterError
from .runlog import RunLog


@dataclass(frozen=True)
class SensorModel:
    """Imperfections of the accelerometer and gyroscope.

    Parameters
    ----------
    accel_noise : float
        White noise standard deviation of the accelerometer, m/s².
    gyro_noise : float
        White noise standard deviation of the gyroscope, rad/s.
    accel_bias : float
        Constant accelerometer offset, m/s².
    gyro_bias : float
        Constant gyroscope offset, rad/s.
    accel_drift : float
        Linear accelerometer drift, m/s² per s.
    gyro_drift : float
        Linear gyroscope drift, rad/s per s.
    sample_rate_hz : float, optional
        Output sample rate, Hz; must divide the simulation rate. Default: the simulation rate.
    digits : int, optional
        Significant digits kept in the written numbers (e.g. 8), default full precision.
    """

    accel_noise: float = 0.0
    gyro_noise: float = 0.0
    accel_bias: float = 0.0
    gyro_bias: float = 0.0
    accel_drift: float = 0.0
    gyro_drift: float = 0.0
    sample_rate_hz: float | None = None
    digits: int | None = None

    def __post_init__(self) -> None:
        for name in ("accel_noise", "gyro_noise"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ParameterError(f"sensor {name} must be a finite standard deviation >= 0")
        for name in ("accel_bias", "gyro_bias", "accel_drift", "gyro_drift"):
            if not math.isfinite(getattr(self, name)):
                raise ParameterError(f"sensor {name} must be finite")
        if self.sample_rate_hz is not None and not (
            math.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0
        ):
            raise ParameterError("sensor sample_rate_hz must be a positive number of Hz")
        if self.digits is not None and not (3 <= self.digits <= 17):
            raise ParameterError("sensor digits must be between 3 and 17 significant digits")


def round_significant(x: NDArray[np.float64], digits: int) -> NDArray[np.float64]:
    """Round to ``digits`` significant digits, as a CSV written with that precision would."""
    with np.errstate(divide="ignore"):
        mag = np.floor(np.log10(np.abs(x)))
    mag[~np.isfinite(mag)] = 0.0
    scale = 10.0 ** (digits - 1 - mag)
    return np.round(x * scale) / scale


def apply_sensor(
    time_s: NDArray[np.float64],
    accel_z_mps2: NDArray[np.float64],
    pitch_rate_radps: NDArray[np.float64],
    speed_mps: NDArray[np.float64],
    sensor: SensorModel,
    *,
    seed: int | None = None,
    chainage_m: NDArray[np.float64] | None = None,
) -> RunLog:
    """Sample, corrupt and round clean signals into a :class:`RunLog`.

    Parameters
    ----------
    time_s, accel_z_mps2, pitch_rate_radps, speed_mps : ndarray
        Clean signals on a regular time grid: time (s), vertical body acceleration (m/s²,
        gravity removed), pitch rate (rad/s), speed (m/s).
    sensor : SensorModel
        Imperfections to apply.
    seed : int, optional
        Seed of the noise generator.
    chainage_m : ndarray, optional
        Body-centre chainage at each sample, m, to log as a chainage column.
    """
    t_all = np.asarray(time_s, dtype=np.float64)
    step = 1
    if sensor.sample_rate_hz is not None:
        rate = 1.0 / float(t_all[1] - t_all[0])
        ratio = rate / sensor.sample_rate_hz
        step = int(round(ratio))
        if step < 1 or abs(ratio - step) > 1e-6:
            raise ParameterError(
                f"sensor rate {sensor.sample_rate_hz} Hz must divide the simulation rate "
                f"{rate:g} Hz"
            )
    idx = np.arange(0, t_all.size, step)
    t = t_all[idx]
    rng = np.random.default_rng(seed)
    acc = accel_z_mps2[idx] + sensor.accel_bias + sensor.accel_drift * t
    gyr = pitch_rate_radps[idx] + sensor.gyro_bias + sensor.gyro_drift * t
    if sensor.accel_noise > 0:
        acc = acc + rng.normal(0.0, sensor.accel_noise, t.size)
    if sensor.gyro_noise > 0:
        gyr = gyr + rng.normal(0.0, sensor.gyro_noise, t.size)
    v = speed_mps[idx]
    x = chainage_m[idx] if chainage_m is not None else None
    if sensor.digits is not None:
        acc = round_significant(acc, sensor.digits)
        gyr = round_significant(gyr, sensor.digits)
    return RunLog(time_s=t, accel_z_mps2=acc, pitch_rate_radps=gyr, speed_mps=v, chainage_m=x)
