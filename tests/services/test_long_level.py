"""The long level D2 is filtered from (``track_run_levels.long_mm``): kept to its stated
resolution with its gaps, and placed on exactly the track-grid points of the level it is
stored with, whatever the run's offset."""

from __future__ import annotations

import numpy as np

from app.services.storage.profiles import (
    LONG_LEVEL_RESOLUTION_MM,
    pack_long_level,
    unpack_long_level,
)
from app.services.track.alignment import on_track_grid
from app.services.track.integrate import _on_points
from engine.chainage import GRID_STEP_M


def test_long_level_keeps_its_resolution_and_gaps() -> None:
    """Values come back within half the resolution; NaN (no pass) stays NaN, nowhere else."""
    rng = np.random.default_rng(0)
    values = np.cumsum(rng.normal(0.0, 0.05, 1000))
    values[100:130] = np.nan
    back = unpack_long_level(pack_long_level(values))
    assert np.array_equal(np.isnan(back), np.isnan(values))
    ok = np.isfinite(values)
    assert np.max(np.abs(back[ok] - values[ok])) <= 0.5 * LONG_LEVEL_RESOLUTION_MM + 1e-12


def test_long_level_lands_on_the_levels_points() -> None:
    """Shifted by a run's offset, the long level is sampled on the level's own points: same
    first index and length, the shifted values where both exist, NaN beyond the level's."""
    x = np.arange(0.0, 300.0, GRID_STEP_M) + 12.0
    level = np.sin(2 * np.pi * x / 20.0)
    long = np.sin(2 * np.pi * x / 60.0)
    long[:40] = np.nan  # the long level may start later than the level
    offset = 1.3
    i_lo, on_grid = on_track_grid(x, level, offset)
    placed = _on_points(x, long, offset, i_lo, on_grid.size)
    assert placed.size == on_grid.size
    chain = (i_lo + np.arange(placed.size)) * GRID_STEP_M
    ok = np.isfinite(placed)
    want = np.sin(2 * np.pi * (chain[ok] - offset) / 60.0)
    assert np.max(np.abs(placed[ok] - want)) < 1e-3  # linear interpolation of a 60 m wave
    assert not ok[: int(40 - offset / GRID_STEP_M) - 1].any()
    assert ok[-10:].all()


def test_a_kept_long_level_goes_back_to_the_runs_own_chainage() -> None:
    """A realignment rebuilds a run from its own chainage: its kept long level (stored on
    track-grid points at the old offset) comes back there, so it can be placed again."""
    from app.services.track.aggregate import CHUNK_POINTS, chunked
    from app.services.track.integrate import _long_level_back

    x = np.arange(0.0, 600.0, GRID_STEP_M) + 30.0  # the run's chainage as processed
    long = np.sin(2 * np.pi * x / 45.0)
    offset = -2.7
    i_lo, on_grid = on_track_grid(x, long, offset)
    rows = [(c, pack_long_level(v)) for c, v in chunked(i_lo, on_grid)[2].items()]
    assert rows and all(len(unpack_long_level(b)) == CHUNK_POINTS for _, b in rows)
    back = _long_level_back(rows, offset, x)
    assert back is not None
    ok = np.isfinite(back)
    assert ok[8:-8].all()
    assert np.max(np.abs(back[ok] - long[ok])) < 2e-3  # two interpolations of a 45 m wave
    assert _long_level_back([], offset, x) is None
