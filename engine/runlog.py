"""A run log in canonical SI form: what the inversion consumes.

Whatever the logger wrote (column names, units, gravity included or not), it is turned into a
:class:`RunLog` by :mod:`engine.logio` before any numerics run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .errors import LogFormatError
from .scan import first_at_most, first_nonfinite

COLUMNS = ("time_s", "accel_z_mps2", "pitch_rate_radps", "speed_mps", "chainage_m", "wheel_load_n")
"""The fields of a :class:`RunLog`, each an array of one value per sample (or None)."""


@dataclass(frozen=True)
class RunLog:
    """One pass of an instrumented vehicle, in SI units.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample times, s, strictly increasing with a constant step.
    accel_z_mps2 : ndarray, shape (n,)
        Vertical body acceleration at the centre of gravity, m/s², gravity removed, positive up.
    pitch_rate_radps : ndarray, shape (n,)
        Body pitch rate, rad/s, positive nose-up.
    speed_mps : ndarray, shape (n,), optional
        Vehicle speed, m/s (> 0). Needed unless ``chainage_m`` is given.
    chainage_m : ndarray, shape (n,), optional
        Chainage of the body centre at each sample, m (odometer).
    wheel_load_n : ndarray, shape (n,), optional
        Static wheel load from a load-weigh system, N (mean of the half-car's wheels): what the
        vehicle carries on this run. Not used by the inversion itself; see
        :meth:`static_wheel_load_n`.
    lat_deg, lon_deg : ndarray, shape (n,), optional
        GNSS position (WGS84 latitude and longitude, degrees) at each sample, NaN at samples
        without a fix (fixes come at 1-10 Hz). Both or neither.
    """

    time_s: NDArray[np.float64]
    accel_z_mps2: NDArray[np.float64]
    pitch_rate_radps: NDArray[np.float64]
    speed_mps: NDArray[np.float64] | None = None
    chainage_m: NDArray[np.float64] | None = None
    wheel_load_n: NDArray[np.float64] | None = None
    lat_deg: NDArray[np.float64] | None = None
    lon_deg: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        n = np.shape(self.time_s)[0] if np.ndim(self.time_s) == 1 else -1
        if n < 2:
            raise LogFormatError("a run log needs a 1-D time column with at least 2 samples")
        for name in COLUMNS:
            arr = getattr(self, name)
            if arr is None:
                continue
            a = np.ascontiguousarray(arr, dtype=np.float64)
            if a.shape != (n,):
                raise LogFormatError(
                    f"column {name} has shape {a.shape}, expected ({n},) like time_s", column=name
                )
            i = first_nonfinite(a)
            if i is not None:
                raise LogFormatError(
                    f"column {name} sample {i} is {a[i]}: every value must be a finite number",
                    column=name, row=i + 2,
                )  # fmt: skip
            object.__setattr__(self, name, a)
        self._check_fixes(n)
        if self.speed_mps is None and self.chainage_m is None:
            raise LogFormatError(
                "a run log needs a speed column (m/s) or a chainage column (m)", column="speed_mps"
            )
        i = first_at_most(np.diff(self.time_s), 0.0)
        if i is not None:
            raise LogFormatError(
                f"time must be strictly increasing: sample {i + 1} ({self.time_s[i + 1]} s) "
                f"does not follow sample {i} ({self.time_s[i]} s)",
                column="time_s", row=i + 3,
            )  # fmt: skip

    def _check_fixes(self, n: int) -> None:
        if (self.lat_deg is None) != (self.lon_deg is None):
            raise LogFormatError(
                "a run log's positions need both latitude and longitude", column="lat_deg"
            )
        if self.lat_deg is None or self.lon_deg is None:
            return
        lat = np.ascontiguousarray(self.lat_deg, dtype=np.float64)
        lon = np.ascontiguousarray(self.lon_deg, dtype=np.float64)
        for name, a, limit in (("lat_deg", lat, 90.0), ("lon_deg", lon, 180.0)):
            if a.shape != (n,):
                raise LogFormatError(
                    f"column {name} has shape {a.shape}, expected ({n},) like time_s", column=name
                )
            bad = np.isinf(a) | (np.abs(a) > limit)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise LogFormatError(
                    f"column {name} sample {i} is {a[i]}: degrees within ±{limit:g} expected "
                    "(NaN where there is no fix)",
                    column=name, row=i + 2,
                )  # fmt: skip
        if not np.array_equal(np.isnan(lat), np.isnan(lon)):
            i = int(np.flatnonzero(np.isnan(lat) != np.isnan(lon))[0])
            raise LogFormatError(
                f"sample {i} has a latitude or a longitude but not both: a fix needs both",
                column="lat_deg", row=i + 2,
            )  # fmt: skip
        object.__setattr__(self, "lat_deg", lat)
        object.__setattr__(self, "lon_deg", lon)

    @property
    def has_fixes(self) -> bool:
        """Whether the log carries at least one GNSS position fix."""
        return self.lat_deg is not None and bool(np.isfinite(self.lat_deg).any())

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.time_s.shape[0])

    @property
    def dt(self) -> float:
        """Mean sample step, s."""
        return float((self.time_s[-1] - self.time_s[0]) / (self.n - 1))

    @property
    def sample_rate_hz(self) -> float:
        """Mean sample rate, Hz."""
        return 1.0 / self.dt

    @property
    def duration_s(self) -> float:
        """Time from first to last sample, s."""
        return float(self.time_s[-1] - self.time_s[0])

    def speed(self) -> NDArray[np.float64]:
        """Speed at each sample, m/s: the speed column, or the chainage column differentiated."""
        if self.speed_mps is not None:
            return self.speed_mps
        assert self.chainage_m is not None
        return np.abs(np.gradient(self.chainage_m, self.time_s))

    def static_wheel_load_n(self) -> float | None:
        """The load-weigh column's static wheel load, N: its median (a load-weigh reading
        jitters with the body's motion; the load itself does not change while moving), or None
        when the log has none."""
        if self.wheel_load_n is None:
            return None
        return float(np.median(self.wheel_load_n))

    def distance(self) -> NDArray[np.float64]:
        """Distance travelled since the first sample, m (from chainage or integrated speed)."""
        if self.chainage_m is not None:
            return np.abs(self.chainage_m - self.chainage_m[0])
        v = self.speed()
        dt = np.diff(self.time_s)
        out = np.empty(self.n)
        out[0] = 0.0
        np.cumsum(0.5 * (v[1:] + v[:-1]) * dt, out=out[1:])
        return out
