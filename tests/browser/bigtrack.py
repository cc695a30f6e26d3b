"""A large generated track for the chainage-map scale check: many runs over a long line.

The runs, their soft spots and part of their profiles are written straight into the service's
database (the same tables an upload fills), because pushing 50 x 100 km logs through the
inversion would take far longer than the check itself. Soft spots repeat from run to run
around fixed "true" zones (detected with a probability, with chainage scatter), plus one-off
false alarms, so the zones of the map have realistic multiplicities.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np
from sqlalchemy import select

from app.db.migrate import upgrade
from app.db.models import Run, SoftSpot, Track, Vehicle
from app.db.session import Database
from app.services.storage.profiles import insert_profile

GRID_STEP_M = 0.25
"""Chainage step of a stored profile, m (the engine's default grid)."""


@dataclass(frozen=True)
class BigTrack:
    """What was generated."""

    name: str
    n_runs: int
    length_m: float
    n_spots: int
    profile_from_m: float
    profile_to_m: float
    zone_peaks_m: np.ndarray


def fill_big_track(
    url: str,
    *,
    name: str = "Big line",
    n_runs: int = 50,
    length_m: float = 100_000.0,
    n_zones: int = 150,
    detect_prob: float = 0.85,
    false_alarms_per_run: int = 10,
    profile_from_m: float = 40_000.0,
    profile_to_m: float = 50_000.0,
    seed: int = 0,
) -> BigTrack:
    """Create a track of ``n_runs`` processed runs over ``length_m`` metres.

    Every run covers the whole line (its extent is stored) and has its soft spots; the
    per-chainage profile (0.25 m grid) is stored between ``profile_from_m`` and
    ``profile_to_m`` only, which is what a zoomed heatmap or a zone window reads.
    """
    rng = np.random.default_rng(seed)
    db = Database(url)
    upgrade(db)
    zone_peaks = np.sort(rng.uniform(500.0, length_m - 500.0, n_zones))
    zone_depth = rng.uniform(0.08, 0.6, n_zones)
    t0 = datetime(2025, 1, 6, 6, 0, tzinfo=UTC)
    n_spots = 0
    grid = np.arange(profile_from_m, profile_to_m, GRID_STEP_M)
    with db.session() as s:
        vehicle = s.scalar(select(Vehicle).order_by(Vehicle.id))
        assert vehicle is not None, "the migrations create the Table 1 vehicle"
        track = Track(
            name=name,
            description=f"generated: {n_runs} runs over {length_m / 1000:g} km",
            rail="UIC60",
            k_nominal=8e7,
            spacing=0.6,
            EI=6.4155e6,
            mass_per_m=60.21,
            c_support=5e4,
        )
        s.add(track)
        s.flush()
        for k in range(n_runs):
            recorded = t0 + timedelta(days=k, hours=float(rng.uniform(0, 12)))
            seen = rng.random(n_zones) < detect_prob
            peaks = zone_peaks[seen] + rng.normal(0.0, 0.4, int(seen.sum()))
            depths = np.clip(zone_depth[seen] * rng.normal(1.0, 0.15, int(seen.sum())), 0.05, None)
            fa = rng.uniform(0.0, length_m, false_alarms_per_run)
            peaks = np.concatenate([peaks, fa])
            depths = np.concatenate([depths, rng.uniform(0.05, 0.12, false_alarms_per_run)])
            widths = rng.uniform(3.0, 8.0, peaks.size)
            order = np.argsort(peaks)
            run = Run(
                track_id=track.id,
                vehicle_id=vehicle.id,
                source="upload",
                original_filename=f"run-{k:02d}.csv",
                recorded_at=recorded,
                processed_at=recorded,
                start_chainage_m=0.0,
                direction="increasing",
                sample_rate_hz=1000.0,
                n_samples=int(length_m / 30.0 * 1000),
                duration_s=length_m / 30.0,
                speed_min_mps=29.0,
                speed_max_mps=31.0,
                chainage_min_m=0.0,
                chainage_max_m=length_m,
                chainage_offset_m=0.0,
                status="done",
                quality={"coverage_m": length_m},
                method="spectral",
                options={},
                n_soft_spots=int(peaks.size),
                processing_s=1.0,
                content_hash=hashlib.sha256(f"{name}-{seed}-{k}".encode()).hexdigest(),
            )
            s.add(run)
            s.flush()
            for i in order:
                p, w, d = float(peaks[i]), float(widths[i]), float(depths[i])
                s.add(
                    SoftSpot(
                        run_id=run.id,
                        start_m=p - w / 2,
                        end_m=p + w / 2,
                        peak_m=p,
                        depth_mm=d,
                        stiffness_loss_pct=float(min(90.0, 20.0 + 100.0 * d)),
                    )
                )
            n_spots += int(peaks.size)
            level = rng.normal(0.0, 0.02, grid.size)
            for p, d, w in zip(peaks, depths, widths, strict=True):
                if profile_from_m - 10 <= p <= profile_to_m + 10:
                    level -= d * np.exp(-0.5 * ((grid - p) / (w / 4)) ** 2)
            force = np.full_like(grid, 58_000.0)  # a steady wheel force, N
            insert_profile(
                s, run.id, grid, level + 0.01, level - 0.01, np.zeros_like(grid),
                force, force,
            )  # fmt: skip
        s.commit()
    db.dispose()
    return BigTrack(name, n_runs, length_m, n_spots, profile_from_m, profile_to_m, zone_peaks)
