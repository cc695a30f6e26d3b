"""Soft spots near the ends of the separable profile (engine/separation.py, ``_soft_spots``)."""

from __future__ import annotations

import numpy as np

from engine.chainage import bandpass_distance
from engine.detect import robust_sigma
from engine.separation import SeparationConfig, _soft_spots, _zone_shapes, zone_depths
from engine.track import TrackParams

STEP_M = 0.25
SPREAD_MM = 0.06
"""Robust spread of the compliance profile as a level dip at 100 kN, mm (the bogie runs')."""


def _red_noise(rng: np.random.Generator, n: int) -> np.ndarray:
    """Band-passed (3-40 m) noise whose density falls as wavelength^-1.5, unit robust spread."""
    f = np.fft.rfftfreq(n, STEP_M)
    spec = np.fft.rfft(rng.standard_normal(n)) / np.maximum(f, 1 / 40.0) ** 1.5
    y = bandpass_distance(np.fft.irfft(spec, n), STEP_M, 3.0, 40.0)
    return y / robust_sigma(y)


def test_near_end_keeps_zones_and_drops_most_long_wave_swings():
    """A 6 m, 50 % zone 12 m from the start of the separable profile and a 32 m swing of the
    compliance (7.5 spreads deep) with its trough 14 m from the other end, in red noise: the
    zone is found on every track; the swing, which the residual's threshold alone reports
    as a soft spot, on fewer than half."""
    trk, cfg = TrackParams(), SeparationConfig()
    x = np.arange(0.0, 400.0, STEP_M)
    shape = dict(_zone_shapes(STEP_M, trk, ((((0.0,), (0.0,)), 1.0),), cfg))[6.0]
    losses, depths = zone_depths(trk, cfg.lambda_min_m, cfg.lambda_max_m, cfg.taper)
    depth_mm = float(np.interp(0.5, losses, depths)) * cfg.reference_load_n
    k, h = int(round(12.0 / STEP_M)), shape.size // 2
    trough = x[-1] - 14.0
    u = x - trough
    swing = np.where(
        np.abs(u) <= 24.0, np.cos(2 * np.pi * u / 32.0) * np.cos(np.pi * u / 48.0) ** 2, 0.0
    )
    zones = swings = 0
    for seed in range(8):
        y = SPREAD_MM * _red_noise(np.random.default_rng(seed), x.size)
        y[: k + h + 1] -= depth_mm * shape[h - k :]
        y -= 7.5 * SPREAD_MM * swing
        spots = _soft_spots(x, y, np.full(x.size, 0.3 * SPREAD_MM), trk, cfg)
        zones += any(abs(s.start_m - 9.0) <= 1.5 and abs(s.end_m - 15.0) <= 1.5 for s in spots)
        swings += any(s.end_m >= trough - 10.0 for s in spots)
    assert zones == 8
    assert swings < 4
