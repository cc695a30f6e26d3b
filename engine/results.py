"""Result objects returned by the engine's processing pipeline."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .detect import Dip


class _Figures:
    """A dataclass whose every field is a float, turned into a plain dict of floats."""

    def to_dict(self) -> dict[str, float]:
        """Plain dict of the fields (what the API and the run's JSON files carry)."""
        return {k: float(v) for k, v in vars(self).items()}


@dataclass(frozen=True)
class SoftSpot(Dip, _Figures):
    """A local dip of the loaded level: a place where the track support is weak.

    The dip's extent and depth are :class:`engine.detect.Dip`'s.

    Attributes
    ----------
    stiffness_loss_pct : float
        Estimated loss of support stiffness against nominal, % (0-100).
    """

    stiffness_loss_pct: float


@dataclass(frozen=True)
class Quality(_Figures):
    """Quality indicators of one processed run.

    Attributes
    ----------
    noise_accel_mps2 : float
        Estimated white-noise level of the accelerometer, m/s² RMS.
    noise_pitch_rate_radps : float
        Estimated white-noise level of the gyroscope, rad/s RMS.
    axle_agreement_mm : float
        RMS difference between front- and rear-axle profiles where both cover the track,
        away from the band-pass's ends (``lambda_max (1 + taper)`` at each end of the common
        stretch), mm.
    coverage_m : float
        Length of track covered by the fused profile, m.
    speed_min_mps, speed_max_mps : float
        Speed range of the run, m/s.
    sample_rate_hz : float
        Sample rate of the log, Hz.
    """

    noise_accel_mps2: float
    noise_pitch_rate_radps: float
    axle_agreement_mm: float
    coverage_m: float
    speed_min_mps: float
    speed_max_mps: float
    sample_rate_hz: float


@dataclass(frozen=True)
class GeometryCheck:
    """Whether a single pass's stiffness-loss figures are valid: is the rail smooth?

    One loaded pass cannot tell a geometric dip of the rail from a soft spot. Where the pass
    itself shows the rail smooth at the noise level (straight-rail simulations, the paper's
    case) its stiffness figures stay valid; otherwise they are withheld.

    Attributes
    ----------
    smooth : bool
        The residual's robust spread is at or below the threshold.
    residual_sigma_mm : float
        Robust spread (1.4826 MAD) of the level minus its 40 m baseline, mm.
    threshold_mm : float
        The criterion's threshold, mm (see :data:`engine.geometry_check.SMOOTH_RAIL_SIGMA_MM`).
    message : str or None
        Plain words when not smooth.
    """

    smooth: bool
    residual_sigma_mm: float
    threshold_mm: float
    message: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of the fields."""
        return asdict(self)


@dataclass(frozen=True)
class DetectionLimit:
    """The smallest stiffness loss a pass can detect, per zone length.

    Attributes
    ----------
    zone_length_m : tuple of float
        Zone lengths, m.
    min_loss_pct : tuple of float
        Smallest detectable loss for each, % of nominal support stiffness; NaN where even
        the largest loss the model reports (:data:`engine.stiffness.MAX_LOSS`) stays below
        the threshold.
    threshold_mm : float
        The detector's depth threshold on this pass, mm.
    """

    zone_length_m: tuple[float, ...]
    min_loss_pct: tuple[float, ...]
    threshold_mm: float

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (NaN as None) with the field names above."""
        return {
            "zone_length_m": [float(x) for x in self.zone_length_m],
            "min_loss_pct": [None if not math.isfinite(x) else float(x) for x in self.min_loss_pct],
            "threshold_mm": float(self.threshold_mm),
        }


@dataclass(frozen=True)
class ProcessResult:
    """Everything the pipeline derives from one run log.

    Attributes
    ----------
    chainage_m : ndarray
        Regular chainage grid of the fused profile, m, increasing.
    level_mm : ndarray
        Fused loaded level on that grid, mm, positive up (band-limited, zero mean).
    front_level_mm, rear_level_mm : ndarray
        Each axle's loaded level on the same grid, mm (NaN where that axle did not pass).
    baseline_mm : ndarray
        Slowly varying baseline the soft spots are measured against, mm.
    soft_spots : list of SoftSpot
        Detected zones, ordered by chainage.
    quality : Quality
        Quality indicators.
    method : str
        Name of the inversion method used.
    extras : dict
        Method-specific diagnostics.
    front_force_n, rear_force_n : ndarray or None
        Each axle's wheel-rail contact force on the same grid, N, compression positive:
        static axle load plus the dynamic part the vehicle equations give from the recovered
        levels (NaN where that axle did not pass; None only for results built by hand).
    geometry_check : GeometryCheck or None
        Whether the rail is smooth at the noise level, i.e. the soft spots' stiffness-loss
        figures are valid (they are NaN when not; None only for results built by hand).
    detection_limit : DetectionLimit or None
        The smallest stiffness loss this pass could detect per zone length, from its own
        detection threshold (None only for results built by hand).
    """

    chainage_m: NDArray[np.float64]
    level_mm: NDArray[np.float64]
    front_level_mm: NDArray[np.float64]
    rear_level_mm: NDArray[np.float64]
    baseline_mm: NDArray[np.float64]
    soft_spots: list[SoftSpot]
    quality: Quality
    method: str
    extras: dict[str, Any] = field(default_factory=dict)
    front_force_n: NDArray[np.float64] | None = None
    rear_force_n: NDArray[np.float64] | None = None
    geometry_check: GeometryCheck | None = None
    detection_limit: DetectionLimit | None = None
