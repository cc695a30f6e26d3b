"""The aggregated profile kept in packed 250 m chunks reads back like the row per grid point it
replaced: a chainage window is inclusive at both ends, only covered points are returned, and
windows that start, end or lie between stored chunks give exactly the points inside them."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from app.db.migrate import upgrade
from app.db.models import Track, TrackProfileChunk
from app.db.session import Database
from app.services.track.aggregate import (
    CHUNK_POINTS,
    CombinedSpot,
    aggregate_chunk_range,
    pack_chunk,
    read_aggregate_grid,
    read_track_profile,
    unpack_chunk,
)
from engine.chainage import GRID_STEP_M

STORED = (3, 4, 7)  # chunks with data; 5 and 6 hold none


@pytest.fixture
def stored(tmp_path: Path):
    """A track whose aggregate covers parts of chunks 3, 4 and 7, with the expected points."""
    db = Database(f"sqlite:///{tmp_path / 'agg.db'}")
    upgrade(db)
    rng = np.random.default_rng(3)
    want: dict[int, tuple[float, float, int]] = {}
    with db.session() as s:
        track = Track(name="A", k_nominal=8e7, spacing=0.6, EI=6.4e6, mass_per_m=60.0,
                      c_support=5e4)  # fmt: skip
        s.add(track)
        s.flush()
        for chunk in STORED:
            n = rng.integers(0, 4, CHUNK_POINTS)
            n[:10] = 0  # uncovered points at a chunk's start
            level = np.where(n > 0, rng.normal(0, 0.3, CHUNK_POINTS), np.nan)
            spread = np.where(n > 0, rng.uniform(0, 0.05, CHUNK_POINTS), np.nan)
            s.add(TrackProfileChunk(track_id=track.id, chunk=chunk,
                                    data=pack_chunk(level, spread, n)))  # fmt: skip
            for k in np.flatnonzero(n).tolist():
                want[chunk * CHUNK_POINTS + k] = (float(level[k]), float(spread[k]), int(n[k]))
        s.commit()
        track_id = track.id
    yield db, track_id, want
    db.dispose()


def test_a_combined_spot_is_kept_as_strict_json_and_read_back() -> None:
    """A combined spot's figures that are not finite (no loss, infinite significance) are
    kept as null, which strict JSON (PostgreSQL) accepts, and read back as NaN / None."""
    spot = CombinedSpot(10.0, 16.0, 13.0, 0.3, None, math.inf, (3, 4), (3, 4, 5))
    kept = json.loads(json.dumps(spot.to_json(), allow_nan=False))
    back = CombinedSpot.from_json(kept)
    assert kept["significance"] is None and kept["supporting"] == [3, 4]
    assert back.loss_pct is None and math.isnan(back.significance)
    assert (back.start_m, back.end_m, back.covering) == (10.0, 16.0, (3, 4, 5))


def test_a_chunk_packs_and_unpacks_exactly() -> None:
    rng = np.random.default_rng(0)
    n = rng.integers(0, 50, CHUNK_POINTS)
    level = np.where(n > 0, rng.normal(0, 1, CHUNK_POINTS), np.nan)
    spread = np.abs(level) / 7
    got = unpack_chunk(pack_chunk(level, spread, n))
    np.testing.assert_array_equal(got[0], level)
    np.testing.assert_array_equal(got[1], spread)
    np.testing.assert_array_equal(got[2], n)
    assert got[2].dtype == np.int64


@pytest.mark.parametrize(
    "from_m, to_m",
    [
        (None, None),
        (750.0, 1000.0),  # on grid points: both ends included
        (750.1, 999.9),  # between grid points
        (1240.0, 1760.0),  # across the empty chunks 5 and 6
        (1300.0, 1700.0),  # only the empty chunks
        (0.0, 10.0),  # before any data
        (1990.0, 1e9),  # past the end
        (999.75, 999.75),  # a single point
    ],
)
def test_a_window_gives_the_covered_points_inside_it(stored, from_m, to_m) -> None:
    db, track_id, want = stored
    with db.session() as s:
        cols = read_track_profile(s, track_id, from_m, to_m)
    lo = -np.inf if from_m is None else from_m
    hi = np.inf if to_m is None else to_m
    inside = sorted(i for i in want if lo <= i * GRID_STEP_M <= hi)
    assert cols["chainage_m"] == [i * GRID_STEP_M for i in inside]
    assert cols["level_mm"] == [want[i][0] for i in inside]
    assert cols["spread_mm"] == [want[i][1] for i in inside]
    assert cols["n_runs"] == [want[i][2] for i in inside]


def test_the_grid_read_has_nan_where_no_run_and_the_range_is_the_stored_chunks(stored) -> None:
    db, track_id, want = stored
    i_lo, i_hi = 4 * CHUNK_POINTS - 5, 7 * CHUNK_POINTS + 20
    with db.session() as s:
        grid = read_aggregate_grid(s, track_id, i_lo, i_hi)
        assert aggregate_chunk_range(s, track_id) == (3, 7)
        assert aggregate_chunk_range(s, track_id + 1) is None
    assert grid.size == i_hi - i_lo + 1
    expect = np.array([want[i][0] if i in want else np.nan for i in range(i_lo, i_hi + 1)])
    np.testing.assert_array_equal(grid, expect)
