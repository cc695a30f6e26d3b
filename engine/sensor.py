"""Sensor model: turns clean simulated signals into the log an IMU would write."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from .errors import ParameterError
from .runlog import RunLog

_NON_NEGATIVE = (
    "accel_noise", "gyro_noise", "accel_noise_density", "gyro_noise_density",
    "accel_bias_instability", "gyro_bias_instability", "accel_lsb", "gyro_lsb",
    "time_jitter_s",
)  # fmt: skip


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
    accel_noise_density : float
        White-noise density of the accelerometer, m/s²/√Hz (a datasheet's µg/√Hz times
        9.81e-6). It adds ``density × √(fs/2)`` per sample at the output rate ``fs`` (the
        log's anti-alias band), in quadrature with ``accel_noise``.
    gyro_noise_density : float
        White-noise density of the gyroscope, rad/s/√Hz (an angular random walk in °/√h is
        ``radians(ARW / 60)``), added like ``accel_noise_density``.
    accel_bias_instability, gyro_bias_instability : float
        Standard deviation of the slow bias wander (m/s², rad/s): a first-order Gauss-Markov
        process with correlation time ``bias_correlation_s``, starting from a draw of its
        stationary distribution (a datasheet's in-run bias stability).
    bias_correlation_s : float
        Correlation time of the bias wander, s.
    accel_lsb, gyro_lsb : float
        Quantisation step of the output registers, m/s² and rad/s per LSB (0: none).
    time_jitter_s : float
        Standard deviation of the sample-time error, s: sample ``i`` holds the signal at
        ``t_i + e_i`` while the log says ``t_i`` (a free-running logger's clock).
    """

    accel_noise: float = 0.0
    gyro_noise: float = 0.0
    accel_bias: float = 0.0
    gyro_bias: float = 0.0
    accel_drift: float = 0.0
    gyro_drift: float = 0.0
    sample_rate_hz: float | None = None
    digits: int | None = None
    accel_noise_density: float = 0.0
    gyro_noise_density: float = 0.0
    accel_bias_instability: float = 0.0
    gyro_bias_instability: float = 0.0
    bias_correlation_s: float = 100.0
    accel_lsb: float = 0.0
    gyro_lsb: float = 0.0
    time_jitter_s: float = 0.0

    def __post_init__(self) -> None:
        for name in _NON_NEGATIVE:
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ParameterError(
                    f"sensor {name} must be a finite number >= 0, got {v}", field=name
                )
        if not (math.isfinite(self.bias_correlation_s) and self.bias_correlation_s > 0):
            raise ParameterError(
                "sensor bias_correlation_s must be a positive number of seconds",
                field="bias_correlation_s",
            )
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


def white_noise_std(base: float, density: float, sample_rate_hz: float) -> float:
    """Per-sample white-noise standard deviation of a sensor logged at ``sample_rate_hz``.

    ``density`` (unit/√Hz) over the anti-alias band ``fs/2`` in quadrature with ``base``
    (unit); ``base`` itself when there is no density.
    """
    if density == 0.0:
        return base
    return math.hypot(base, density * math.sqrt(0.5 * sample_rate_hz))


def gauss_markov(
    rng: np.random.Generator, n: int, dt: float, sigma: float, tau: float
) -> NDArray[np.float64]:
    """A first-order Gauss-Markov sequence of stationary standard deviation ``sigma``.

    ``b[k+1] = phi b[k] + sqrt(1 - phi²) sigma w[k]`` with ``phi = exp(-dt / tau)``, started
    from a draw of the stationary distribution: a bias that wanders over ``tau`` seconds.
    """
    phi = math.exp(-dt / tau)
    w = rng.standard_normal(n) * (sigma * math.sqrt(1.0 - phi * phi))
    w[0] = sigma * rng.standard_normal()
    out: NDArray[np.float64] = lfilter([1.0], [1.0, -phi], w)
    return out


def quantise(x: NDArray[np.float64], lsb: float) -> NDArray[np.float64]:
    """``x`` rounded to whole multiples of ``lsb`` (unchanged when ``lsb`` is 0)."""
    if lsb <= 0:
        return x
    out: NDArray[np.float64] = np.round(x / lsb) * lsb
    return out


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
    dt_out = float(t_all[1] - t_all[0]) * step
    fs = 1.0 / dt_out
    rng = np.random.default_rng(seed)
    sa = white_noise_std(sensor.accel_noise, sensor.accel_noise_density, fs)
    sg = white_noise_std(sensor.gyro_noise, sensor.gyro_noise_density, fs)
    # the white noise is drawn first, as it always was: a model without the newer
    # imperfections writes the same log for the same seed
    noise_a = rng.normal(0.0, sa, t.size) if sa > 0 else None
    noise_g = rng.normal(0.0, sg, t.size) if sg > 0 else None
    if sensor.time_jitter_s > 0:
        when = t + rng.normal(0.0, sensor.time_jitter_s, t.size)
        acc = np.interp(when, t_all, accel_z_mps2)
        gyr = np.interp(when, t_all, pitch_rate_radps)
    else:
        acc = accel_z_mps2[idx]
        gyr = pitch_rate_radps[idx]
    acc = acc + sensor.accel_bias + sensor.accel_drift * t
    gyr = gyr + sensor.gyro_bias + sensor.gyro_drift * t
    if noise_a is not None:
        acc = acc + noise_a
    if noise_g is not None:
        gyr = gyr + noise_g
    tau = sensor.bias_correlation_s
    if sensor.accel_bias_instability > 0:
        acc = acc + gauss_markov(rng, t.size, dt_out, sensor.accel_bias_instability, tau)
    if sensor.gyro_bias_instability > 0:
        gyr = gyr + gauss_markov(rng, t.size, dt_out, sensor.gyro_bias_instability, tau)
    acc = quantise(acc, sensor.accel_lsb)
    gyr = quantise(gyr, sensor.gyro_lsb)
    v = speed_mps[idx]
    x = chainage_m[idx] if chainage_m is not None else None
    if sensor.digits is not None:
        acc = round_significant(acc, sensor.digits)
        gyr = round_significant(gyr, sensor.digits)
    return RunLog(time_s=t, accel_z_mps2=acc, pitch_rate_radps=gyr, speed_mps=v, chainage_m=x)


STANDARD_GRAVITY = 9.80665
"""m/s² per g: a datasheet's µg/√Hz in m/s²/√Hz."""


@dataclass(frozen=True)
class SensorGrade:
    """A class of IMU described by its datasheet figures (what a SensorModel is built from).

    Attributes
    ----------
    name : str
        Identifier (the API's and the CLI's ``sensor_grade``).
    label : str
        Plain words for people.
    accel_density_ug : float
        Accelerometer noise density, µg/√Hz.
    gyro_arw_deg_rth : float
        Gyroscope angular random walk, °/√h.
    accel_bias_mps2, gyro_bias_radps : float
        Largest bias left in a pass (turn-on repeatability after the logger's own zeroing),
        m/s² and rad/s; each pass draws its own within ±this.
    accel_bias_instability_ug, gyro_bias_instability_deg_h : float
        In-run bias stability, µg and °/h (the slow wander).
    accel_lsb_mg, gyro_lsb_dps : float
        Output register resolution, mg and °/s per LSB.
    time_jitter_us : float
        Standard deviation of the logger's sample-time error, µs.
    source : str
        Where the figures come from.
    """

    name: str
    label: str
    accel_density_ug: float
    gyro_arw_deg_rth: float
    accel_bias_mps2: float
    gyro_bias_radps: float
    accel_bias_instability_ug: float
    gyro_bias_instability_deg_h: float
    accel_lsb_mg: float
    gyro_lsb_dps: float
    time_jitter_us: float
    source: str

    @property
    def accel_noise_density(self) -> float:
        """Accelerometer noise density, m/s²/√Hz."""
        return self.accel_density_ug * 1e-6 * STANDARD_GRAVITY

    @property
    def gyro_noise_density(self) -> float:
        """Gyroscope noise density, rad/s/√Hz (1 °/√h is 1/60 °/s/√Hz)."""
        return math.radians(self.gyro_arw_deg_rth / 60.0)

    def white_noise(self, sample_rate_hz: float) -> tuple[float, float]:
        """Per-sample white noise (accelerometer m/s², gyroscope rad/s) at a log rate, Hz."""
        return (
            white_noise_std(0.0, self.accel_noise_density, sample_rate_hz),
            white_noise_std(0.0, self.gyro_noise_density, sample_rate_hz),
        )

    def sensor(
        self, sample_rate_hz: float, seed: int | None = None, *, digits: int | None = 8
    ) -> SensorModel:
        """The :class:`SensorModel` of one pass logged at ``sample_rate_hz`` (Hz).

        ``seed`` draws the pass's biases uniformly within ± the grade's figures; without a
        seed both biases take their full (largest) value.
        """
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise ParameterError(
                f"sample_rate_hz must be a positive number of Hz, got {sample_rate_hz}",
                field="sample_rate_hz",
            )
        if seed is None:
            ba, bg = self.accel_bias_mps2, self.gyro_bias_radps
        else:
            u = np.random.default_rng(seed).uniform(-1.0, 1.0, 2)
            ba, bg = float(u[0]) * self.accel_bias_mps2, float(u[1]) * self.gyro_bias_radps
        return SensorModel(
            accel_bias=ba,
            gyro_bias=bg,
            sample_rate_hz=sample_rate_hz,
            digits=digits,
            accel_noise_density=self.accel_noise_density,
            gyro_noise_density=self.gyro_noise_density,
            accel_bias_instability=self.accel_bias_instability_ug * 1e-6 * STANDARD_GRAVITY,
            gyro_bias_instability=math.radians(self.gyro_bias_instability_deg_h / 3600.0),
            accel_lsb=self.accel_lsb_mg * 1e-3 * STANDARD_GRAVITY,
            gyro_lsb=math.radians(self.gyro_lsb_dps),
            time_jitter_s=self.time_jitter_us * 1e-6,
        )


_Figures = tuple[float, float, float, float, float, float, float, float, float]


def _grades(*rows: tuple[str, str, _Figures, str]) -> dict[str, SensorGrade]:
    """Grades by name from rows ``(name, label, figures, source)``, the figures in
    :class:`SensorGrade`'s field order (``accel_density_ug`` to ``time_jitter_us``)."""
    out = {}
    for name, label, (a, g, ba, bg, wa, wg, la, lg, jit), src in rows:
        out[name] = SensorGrade(name, label, a, g, ba, bg, wa, wg, la, lg, jit, src)
    return out


_FIBRE_ACCEL_UG = 0.005 / (1e-6 * STANDARD_GRAVITY * math.sqrt(500.0))
_FIBRE_GYRO_DEG_RTH = math.degrees(1e-4 / math.sqrt(500.0)) * 60.0

SENSOR_GRADES: dict[str, SensorGrade] = _grades(
    # figures: accel µg/√Hz, gyro °/√h, biases m/s² and rad/s, bias wander µg and °/h,
    # resolution mg and °/s, jitter µs
    # the earlier sample sets' noise at 1 kHz (0.005 m/s², 1e-4 rad/s) as densities
    ("fibre-optic", "fibre-optic gyro, navigation-grade accelerometer",
     (_FIBRE_ACCEL_UG, _FIBRE_GYRO_DEG_RTH, 0.02, 2e-4, 5.0, 0.05, 0.0, 0.0, 1.0),
     "the earlier sample sets (shared docs/sensors.md); wander and jitter assumed"),
    ("tactical-mems", "tactical MEMS (ADIS16495 class)",
     (25.0, 0.09, 0.02, math.radians(0.002), 3.2, 0.8, 0.25, 0.00625, 1.0),
     "ADIS16495-1 data sheet Rev. C (ARW, in-run bias stability, 16-bit scales)"),
    ("industrial-mems", "industrial MEMS",
     (60.0, 0.2, 0.03, math.radians(0.005), 15.0, 5.0, 0.25, 0.0125, 5.0),
     "shared docs/sensors.md; wander, resolution and jitter assumed between the two data "
     "sheets"),
    ("consumer-mems", "consumer MEMS (ADIS16448 class)",
     (230.0, 0.66, 0.05, math.radians(0.02), 250.0, 14.5, 0.833, 0.04, 20.0),
     "ADIS16448 data sheet (noise density 0.23 mg/√Hz, ARW 0.66 °/√h, in-run bias stability, "
     "16-bit scales)"),
)  # fmt: skip
"""The IMU classes a fleet fits, best first (figures and sources in docs/sensors.md)."""


def sensor_for_grade(
    grade: str, sample_rate_hz: float, seed: int | None = None, *, digits: int | None = 8
) -> SensorModel:
    """The :class:`SensorModel` of a pass logged by a ``grade`` IMU at ``sample_rate_hz``.

    Parameters
    ----------
    grade : str
        A name of :data:`SENSOR_GRADES`.
    sample_rate_hz : float
        Output rate of the log, Hz (the noise densities are integrated over half of it).
    seed : int, optional
        Draws the pass's biases within ± the grade's figures (full bias without a seed).
    digits : int, optional
        Significant digits written (8 by default, as the logger's CSV).

    Raises
    ------
    ParameterError
        ``field="sensor_grade"``: an unknown grade.
    """
    if grade not in SENSOR_GRADES:
        raise ParameterError(
            f"unknown sensor grade {grade!r}; expected one of {', '.join(SENSOR_GRADES)}",
            field="sensor_grade",
        )
    return SENSOR_GRADES[grade].sensor(sample_rate_hz, seed, digits=digits)
