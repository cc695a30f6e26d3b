"""The detector's running means (a matched filter for wide dips): what one pass can see."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from engine.detect import DetectionConfig, find_dips
from engine.errors import ParameterError
from engine.pipeline import process_run
from engine.sensor import sensor_for_grade
from engine.setup import RunSetup, prepare_run
from engine.synthetic import make_run, to_runlog
from engine.track import SoftZone
from engine.vehicle import TABLE1
from engine.visibility import detection_limit

STEP = 0.1


def noise(seed: int, n: int = 8000) -> np.ndarray:
    """Band-limited noise of unit spread, correlated over about a metre as a profile's is."""
    x = gaussian_filter1d(np.random.default_rng(seed).normal(size=n), 0.6 / STEP)
    return x / x.std()


def test_a_wide_shallow_dip_is_found_through_the_running_mean_and_noise_alone_is_not() -> None:
    """A 9 m dip of 3.5 noise spreads is under the residual's 5-spread threshold but stands out
    of its running mean; the same noise without the dip gives no dip at any width."""
    g = np.arange(8000) * STEP
    dip = np.where(np.abs(g - 400.0) <= 4.5, -3.5, 0.0)
    hits, misses, false = 0, 0, 0
    for seed in range(6):
        r = noise(seed) + gaussian_filter1d(dip, 0.5 / STEP)
        raw, _ = find_dips(g, r, DetectionConfig(matched_m=()))
        found, _ = find_dips(g, r, DetectionConfig())
        missed = not any(d.start_m <= 404.5 and d.end_m >= 395.5 for d in raw)
        misses += missed
        hit = [d for d in found if d.start_m <= 404.5 and d.end_m >= 395.5]
        hits += bool(hit)
        if hit and missed:  # its extent is the dip's, its depth the residual's deepest inside
            assert abs(hit[0].start_m - 395.5) < 3.0 and abs(hit[0].end_m - 404.5) < 3.0
            assert hit[0].depth_mm == pytest.approx(-r[int(round(hit[0].peak_m / STEP))])
        false += len(find_dips(g, noise(100 + seed), DetectionConfig())[0])
    assert misses >= 3 and hits == 6 and false == 0


def test_matched_widths_are_checked_and_lower_the_limit_of_long_zones() -> None:
    """Widths must be positive and shorter than the baseline window; a width whose noise
    falls more than the zone's dip lowers the detection limit of a long zone."""
    with pytest.raises(ParameterError) as e:
        DetectionConfig(matched_m=(50.0,))
    assert e.value.field == "matched_m"
    band = {
        "load": float(np.mean(TABLE1.static_wheel_loads())), "lambda_min_m": 3.0,
        "lambda_max_m": 40.0, "taper": 0.3, "step_m": 0.25, "baseline_window_m": 40.0,
        "zone_lengths_m": (9.6,),
    }  # fmt: skip
    alone = detection_limit(0.12, **band).min_loss_pct[0]
    with_mean = detection_limit(0.12, matched=((8.0, 0.065),), **band).min_loss_pct[0]
    assert with_mean < 0.75 * alone


@pytest.mark.slow
def test_one_tactical_pass_finds_every_zone_under_a_speed_ramp_with_a_vehicle_off() -> None:
    """One tactical-MEMS pass over a fresh track (supports scattered, a 15 % speed ramp, the
    vehicle 8 % off the registered one, the start 0.7 m off) finds every zone and no false
    zone; the 9.6 m zone of 30 % is one the residual alone misses on this pass (measured:
    ``matched_m=()`` finds the other two only)."""
    zones = [SoftZone(90.0, 93.0, 0.45), SoftZone(160.2, 169.8, 0.3), SoftZone(240.0, 246.0, 0.4)]
    veh = replace(TABLE1, ms=1.08 * TABLE1.ms, ks2=0.93 * TABLE1.ks2)
    run = make_run(
        length=330.0, zones=zones, jitter=0.05, speed=(19.0, 22.0), vehicle=veh,
        sim_rate_hz=500.0, seed=41,
    )  # fmt: skip
    log = to_runlog(run.sim, sensor_for_grade("tactical-mems", 500.0, seed=7), seed=8)
    err = 0.7
    res = process_run(prepare_run(log, RunSetup(start_chainage_m=run.start_chainage_m + err)))
    spots = [(s.start_m - err, s.end_m - err) for s in res.soft_spots]
    found = [any(b >= z.start_m and a <= z.end_m for a, b in spots) for z in zones]
    false = [s for s in spots if not any(s[1] >= z.start_m and s[0] <= z.end_m for z in zones)]
    assert all(found) and not false, (found, false)
