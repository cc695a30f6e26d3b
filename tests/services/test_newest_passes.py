"""A chunk's aggregate and its geometry/stiffness separation are made of its newest runs by
recording time (``NEWEST_PASSES``), not of every run ever stored: a late upload of an old run
does not enter, a deleted newest run lets the next one in, and the separation reads the same
runs. Older runs' aligned levels stay stored."""

from __future__ import annotations

import hashlib
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest

import app.services.track.aggregate as aggregate
from app.db.migrate import upgrade
from app.db.models import Run, Track, TrackRunLevels, Vehicle
from app.db.session import Database
from app.services.track.aggregate import (
    CHUNK_POINTS,
    drop_run_levels,
    read_aggregate,
    recompute_aggregate,
    store_run_levels,
)
from app.services.track.separation_store import read_passes

LIMIT = 3
T0 = datetime(2026, 3, 1, tzinfo=UTC)


@pytest.fixture
def db(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(aggregate, "NEWEST_PASSES", LIMIT)
    database = Database(f"sqlite:///{tmp_path / 'newest.db'}")
    upgrade(database)
    yield database
    database.dispose()


def _track(db: Database) -> tuple[int, int]:
    with db.session() as s:
        vehicle = s.query(Vehicle).order_by(Vehicle.id).first()
        assert vehicle is not None
        track = Track(name="N", k_nominal=8e7, spacing=0.6, EI=6.4e6, mass_per_m=60.0,
                      c_support=5e4)  # fmt: skip
        s.add(track)
        s.commit()
        return track.id, vehicle.id


def _add_run(db: Database, track_id: int, vehicle_id: int, day: float | None,
             level_mm: float) -> int:  # fmt: skip
    """A run recorded ``day`` days after T0 (None: no recording time) whose aligned level is
    ``level_mm`` over chunks 2 and 3, with a wheel force; the aggregate recomputed."""
    with db.session() as s:
        run = Run(
            track_id=track_id, vehicle_id=vehicle_id, source="upload",
            recorded_at=None if day is None else T0 + timedelta(days=day),
            start_chainage_m=0.0, direction="increasing", sample_rate_hz=1000.0,
            n_samples=1000, duration_s=1.0, speed_min_mps=30.0, speed_max_mps=30.0,
            status="done", options={}, attempts=1,
            content_hash=hashlib.sha256(f"{day}-{level_mm}".encode()).hexdigest(),
        )  # fmt: skip
        s.add(run)
        s.flush()
        levels = np.full(2 * CHUNK_POINTS, level_mm)
        force = np.full(2 * CHUNK_POINTS, 60e3 + 1e3 * level_mm)
        chunks = store_run_levels(s, track_id, run.id, 2 * CHUNK_POINTS, levels, force)
        assert chunks == (2, 3)
        recompute_aggregate(s, track_id, *chunks)
        s.commit()
        return run.id


def _aggregate(db: Database, track_id: int) -> tuple[float, int]:
    """The aggregate's level (mm) and run count, the same at every point of chunks 2-3."""
    with db.session() as s:
        span = read_aggregate(s, track_id, 2 * CHUNK_POINTS, 4 * CHUNK_POINTS - 1)
    assert np.unique(span.level_mm).size == 1 and np.unique(span.n_runs).size == 1
    return float(span.level_mm[0]), int(span.n_runs[0])


def test_the_aggregate_is_the_newest_runs_by_recording_time(db: Database) -> None:
    track_id, vehicle_id = _track(db)
    # stored out of recording order: ids do not follow the recording times
    runs = {day: _add_run(db, track_id, vehicle_id, day, level)
            for day, level in ((10, 1.0), (30, 3.0), (20, 2.0), (40, 4.0))}  # fmt: skip
    assert _aggregate(db, track_id) == (3.0, LIMIT)  # median of days 20, 30, 40

    # a late upload of an older recording does not enter; one without a time neither
    _add_run(db, track_id, vehicle_id, 5, -50.0)
    _add_run(db, track_id, vehicle_id, None, -60.0)
    assert _aggregate(db, track_id) == (3.0, LIMIT)
    # a newer one pushes the oldest of the three out
    _add_run(db, track_id, vehicle_id, 50, 9.0)
    assert _aggregate(db, track_id) == (4.0, LIMIT)  # days 30, 40, 50

    # every run's levels stay stored
    with db.session() as s:
        assert s.query(TrackRunLevels.run_id).distinct().count() == 7

    # deleting one of the newest lets the next newest in (day 20)
    with db.session() as s:
        recompute_aggregate(s, track_id, *drop_run_levels(s, runs[40]))
        s.commit()
    assert _aggregate(db, track_id) == (3.0, LIMIT)  # days 20, 30, 50


def test_the_separation_reads_the_same_runs(db: Database) -> None:
    track_id, vehicle_id = _track(db)
    ids = {day: _add_run(db, track_id, vehicle_id, day, float(day)) for day in (3, 1, 4, 2)}
    with db.session() as s:
        passes = read_passes(s, track_id, 1, 4)
    assert sorted(p.id for p in passes) == sorted(ids[d] for d in (2, 3, 4))
    assert all(p.kind == "run" for p in passes)
    # each pass over its own chunks only, with its force
    p = next(p for p in passes if p.id == ids[4])
    assert np.isnan(p.level_mm[:CHUNK_POINTS]).all()
    np.testing.assert_allclose(p.level_mm[CHUNK_POINTS : 3 * CHUNK_POINTS], 4.0)
    np.testing.assert_allclose(p.force_n[CHUNK_POINTS : 3 * CHUNK_POINTS], 64e3)


def test_the_default_bound_keeps_every_run_of_a_small_track() -> None:
    # the bound is for busy lines: the accuracy of a handful of passes is what it was
    assert aggregate.NEWEST_PASSES >= 20
