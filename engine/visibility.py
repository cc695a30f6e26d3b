"""What a pass can see: the smallest stiffness loss its detector would find, per zone length.

The detector (:func:`engine.detect.find_dips`) reports a dip when the residual profile (level
minus its running-median baseline) falls below a threshold: ``noise_factor`` robust standard
deviations of the residual, never less than ``min_depth_mm``. The residual's spread is the
pass's own noise: the sensor noise carried through the inversion, plus rail geometry where the
rail has it. A soft zone of a given length and loss makes a dip of a depth the static beam model
gives (:mod:`engine.stiffness`), passed through the same wavelength band and baseline as a
measured profile. The detector also searches the residual's running means
(``DetectionConfig.matched_m``) against their own spread; a zone's dip is measured through
each. The detection limit is the loss whose dip just reaches a threshold: a zone that weak is
found about half the time; weaker ones are not seen, stronger ones are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from .detect import robust_baseline, running_mean
from .errors import ParameterError
from .results import DetectionLimit
from .stiffness import MAX_LOSS, InfluenceLine, _bandpass_rows, modal_dips
from .track import TrackParams

ZONE_LENGTHS_M = (3.0, 6.0)
"""Zone lengths a run's detection limit is reported for, m: the short and middle soft zones of
the accuracy requirements (3-10 m)."""

_LOSSES = np.linspace(0.0, MAX_LOSS, 48)


@dataclass(frozen=True)
class DipModel:
    """How a zone's dip is modelled and measured, as a processed profile is.

    Attributes
    ----------
    params : TrackParams
        Nominal rail and supports.
    load : float
        Static wheel load, N.
    lambda_min_m, lambda_max_m, taper : float
        The profile's wavelength band, m, and its tapers.
    step_m : float
        Grid step of the profile, m.
    baseline_window_m : float
        The detector's baseline window, m.
    wheel_offsets_m : tuple of float
        The wheels of a measured point relative to it, m, each carrying ``load``: ``(0,)``
        for a half car's axle, ``(+a/2, -a/2)`` for a bogie of wheelbase ``a`` (the profile
        is the mean level under them, :func:`engine.stiffness.fit_zone`).
    """

    params: TrackParams
    load: float
    lambda_min_m: float
    lambda_max_m: float
    taper: float
    step_m: float
    baseline_window_m: float
    wheel_offsets_m: tuple[float, ...] = (0.0,)


def zone_dip_depths(
    zone_length_m: float, losses: NDArray[np.float64], model: DipModel, matched_m: float = 0.0
) -> NDArray[np.float64]:
    """Depth of the dip a zone of ``zone_length_m`` (m) makes for each loss, mm (positive).

    The zone softens the ``round(length / spacing)`` supports (at least one) it covers; its
    modelled loaded-level change under the static wheel load is band-passed and measured
    against the detector's running-median baseline, as ``model`` says; with ``matched_m``
    (m) as the detector sees it through its running mean of that width.
    """
    params, step_m = model.params, model.step_m
    lambda_min_m, lambda_max_m, taper = model.lambda_min_m, model.lambda_max_m, model.taper
    baseline_window_m = model.baseline_window_m
    s = params.spacing
    n = max(1, int(round(zone_length_m / s)))
    sup = (np.arange(n) - 0.5 * (n - 1)) * s
    half = lambda_max_m * (1 + taper) + 0.5 * n * s + baseline_window_m
    g = np.arange(-half, half + 1e-9, step_m)
    infl = InfluenceLine(params)
    # the modes of softening the zone's supports (engine.stiffness.softening_modes), each
    # mode's squared influence band-passed row by row (cheaper than the band-pass matrix)
    lam, Q = np.linalg.eigh(infl(sup[:, None] - sup[None, :]))
    # n wheels at x + o_k, each of the load: the mean level under them changes as one load
    # of load / n with the influence summed over the wheels (engine.stiffness.fit_zone, Notes)
    offsets = model.wheel_offsets_m
    C = Q.T @ sum(infl(g[None, :] + o - sup[:, None]) for o in offsets)
    E = _bandpass_rows(C * C, step_m, lambda_min_m, lambda_max_m, taper)
    dips = modal_dips(lam, E, losses, params.k_nominal, model.load / len(offsets))
    near = np.abs(g) <= 0.5 * n * s + 2 * lambda_min_m
    depth = np.empty(losses.size)
    for i, d in enumerate(dips):
        r = d - robust_baseline(d, step_m, baseline_window_m)
        if matched_m > 0:
            r = running_mean(r, step_m, matched_m)
        depth[i] = max(0.0, -float(np.min(r[near])))
    return depth


@lru_cache(maxsize=64)
def _depth_curve(
    zone_length_m: float, model: DipModel, matched_m: float = 0.0
) -> NDArray[np.float64]:
    """Dip depth against :data:`_LOSSES`, made non-decreasing, mm: one per vehicle, band and
    detector width, so a service's runs reuse it."""
    depth = zone_dip_depths(zone_length_m, _LOSSES, model, matched_m)
    # the dip deepens with the loss (the maximum smooths the baseline's small wobbles)
    out: NDArray[np.float64] = np.maximum.accumulate(depth)
    out.flags.writeable = False
    return out


def detection_limit(
    threshold_mm: float,
    *,
    zone_lengths_m: tuple[float, ...] = ZONE_LENGTHS_M,
    params: TrackParams | None = None,
    load: float,
    lambda_min_m: float,
    lambda_max_m: float,
    taper: float,
    step_m: float,
    baseline_window_m: float,
    wheel_offsets_m: tuple[float, ...] = (0.0,),
    matched: tuple[tuple[float, float], ...] = (),
) -> DetectionLimit:
    """The smallest stiffness loss a detector with ``threshold_mm`` finds, per zone length.

    Parameters
    ----------
    threshold_mm : float
        The detector's depth threshold, mm (what :func:`engine.detect.find_dips` returns).
    zone_lengths_m : tuple of float
        Zone lengths, m.
    params : TrackParams, optional
        Nominal rail and supports (default UIC60 on 80 kN/mm).
    load, lambda_min_m, lambda_max_m, taper, step_m, baseline_window_m : float
        The wheel load (N), the profile's band (m) and tapers, its grid step (m) and the
        detector's baseline window (m): a :class:`DipModel`.
    wheel_offsets_m : tuple of float
        The wheels of a measured point relative to it, m (:class:`DipModel`).
    matched : tuple of (float, float)
        The detector's running-mean widths (m) and their thresholds (mm), as
        :func:`engine.detect.dip_thresholds` gives them after the residual's own; a zone is
        seen when it reaches the threshold at any width.

    Returns
    -------
    DetectionLimit
        The loss (%) whose dip depth equals the threshold, per length (the smallest over the
        widths); it falls as the noise (the threshold) falls.
    """
    if not (math.isfinite(threshold_mm) and threshold_mm > 0):
        raise ParameterError(
            f"threshold_mm must be a positive depth in mm, got {threshold_mm}", field="threshold_mm"
        )
    for z in zone_lengths_m:
        if not (math.isfinite(z) and z > 0):
            raise ParameterError(
                f"zone lengths must be positive numbers of m, got {z}", field="zone_lengths_m"
            )
    model = DipModel(
        params or TrackParams(), float(load), float(lambda_min_m), float(lambda_max_m),
        float(taper), float(step_m), float(baseline_window_m),
        tuple(float(o) for o in wheel_offsets_m),
    )  # fmt: skip
    for w, t in matched:
        if not (math.isfinite(w) and w > 0 and math.isfinite(t) and t > 0):
            raise ParameterError(
                f"matched widths and thresholds must be positive m and mm, got ({w}, {t})",
                field="matched",
            )
    out = []
    for z in zone_lengths_m:
        best = float("nan")
        for w, t in ((0.0, float(threshold_mm)), *matched):
            deepest = _depth_curve(float(z), model, float(w))
            if t <= deepest[-1]:
                best = float(np.fmin(best, 100.0 * np.interp(t, deepest, _LOSSES)))
        out.append(best)
    return DetectionLimit(tuple(float(z) for z in zone_lengths_m), tuple(out), float(threshold_mm))
