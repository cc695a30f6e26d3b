"""The separable stretches the register's stiffness notes rest on: read from the stored
separation's chunks directly (``app.services.track.separation_store.separable_intervals``), they
are the
stretches the whole-line stiffness window (``read_stiffness``, what the API serves) gives,
and each defect's note is the one a linear search over them gives.

The stored chunks are written by hand with every case of the definition: separable runs
inside a chunk, across a chunk boundary, broken by an uncovered point, by a missing chunk,
by a non-separable point, single separable points, and chunks nobody covers.
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from app.db.migrate import upgrade
from app.db.models import Track, TrackStiffness
from app.db.session import Database
from app.services.track.register import stiffness_notes
from app.services.track.separation_store import (
    CHUNK_POINTS,
    GRID_STEP_M,
    NOT_SEPARABLE,
    STIFFNESS_ARRAYS,
    read_stiffness,
    separable_intervals,
)
from engine.register import Defect
from support.app_fixtures import database_url_for


def reference_intervals(x: np.ndarray, sep: np.ndarray) -> list[tuple[float, float]]:
    """The definition, point by point: maximal separable runs of covered grid points, broken
    by a non-separable point or a gap in the covered grid."""
    out: list[tuple[float, float]] = []
    start = None
    for i in range(x.size):
        if sep[i] and start is None:
            start = float(x[i])
        last = i == x.size - 1
        ends = last or not sep[i + 1] or x[i + 1] - x[i] > 1.5 * GRID_STEP_M
        if start is not None and sep[i] and ends:
            out.append((start, float(x[i])))
            start = None
    return out


@pytest.fixture
def db(tmp_path: Path) -> Database:
    database = Database(database_url_for(tmp_path))
    upgrade(database)
    return database


def _store(db: Database, chunks: dict[int, tuple[np.ndarray, np.ndarray]]) -> int:
    with db.session() as s:
        track = Track(name="sep", rail="UIC60", k_nominal=8e7, spacing=0.6, EI=6.4155e6,
                      mass_per_m=60.21, c_support=5e4)  # fmt: skip
        s.add(track)
        s.flush()
        for chunk, (n_passes, sep) in chunks.items():
            block = np.zeros((len(STIFFNESS_ARRAYS), CHUNK_POINTS), dtype="<f4")
            block[STIFFNESS_ARRAYS.index("n_passes")] = n_passes
            block[STIFFNESS_ARRAYS.index("separable")] = sep
            s.add(TrackStiffness(track_id=track.id, chunk=chunk, data=block.tobytes(), meta={}))
        s.commit()
        return int(track.id)


def _defect(start_m: float, end_m: float, loss: float | None) -> Defect:
    t = datetime(2026, 1, 1, tzinfo=UTC)
    return Defect(f"d{start_m}", start_m, end_m, (start_m + end_m) / 2, t, t, 1, 1, 0.3, loss,
                  0.0, 0.0, "new", None, 0, None)  # fmt: skip


def test_intervals_match_the_served_window_and_the_definition(db: Database) -> None:
    rng = np.random.default_rng(5)
    chunks = {}
    for chunk in (0, 1, 2, 4, 5, 7):  # 3 and 6 missing: gaps
        n_passes = (rng.random(CHUNK_POINTS) > 0.02).astype(float) * rng.integers(1, 5)
        # long separable runs with some short breaks and single points
        sep = np.sin(np.arange(CHUNK_POINTS) / rng.uniform(5, 60)) > rng.uniform(-0.5, 0.9)
        sep[rng.integers(0, CHUNK_POINTS, 10)] = True
        chunks[chunk] = (n_passes, sep.astype(float))
    chunks[5] = (np.zeros(CHUNK_POINTS), np.zeros(CHUNK_POINTS))  # stored, nobody covers it
    chunks[1][1][-50:] = 1.0  # a separable run across the boundary of chunks 1 and 2
    chunks[2][1][:50] = 1.0
    chunks[1][0][-50:] = chunks[2][0][:50] = 2.0
    track_id = _store(db, chunks)
    with db.session() as s:
        window = read_stiffness(s, track_id)
        x = np.asarray(window.columns["chainage_m"])
        sep = np.asarray(window.columns["separable"], dtype=bool)
        expected = reference_intervals(x, sep)
        got = separable_intervals(s, track_id)
        assert len(expected) > 50
        assert got == expected
        boundary = CHUNK_POINTS * GRID_STEP_M * 2
        assert any(a < boundary - 1 and b > boundary + 1 for a, b in got)

        # each defect's note is the linear search's over the same stretches
        defects = []
        for a in rng.uniform(0, 8 * CHUNK_POINTS * GRID_STEP_M, 400):
            w = float(rng.uniform(0.0, 30.0))
            loss = None if rng.random() < 0.5 else 40.0
            defects.append(_defect(a, a + w, loss))
        for a, b in got[:20]:  # defects exactly on a stretch's ends
            defects.append(_defect(a, b, None))
        notes = stiffness_notes(s, track_id, defects)
    for d, note in zip(defects, notes, strict=True):
        inside = any(a <= d.start_m and b >= d.end_m for a, b in expected)
        # single-run defects: a loss is a single pass's; without one, the stretch decides
        if d.stiffness_loss_pct is not None:
            want = ("single pass", None)
        elif inside:
            want = (None, None)
        else:
            want = (None, NOT_SEPARABLE)
        assert note == want, (d, note, want)
    assert sum(n == (None, None) for n in notes) >= 20


def test_no_separation_stored(db: Database) -> None:
    track_id = _store(db, {})
    with db.session() as s:
        assert separable_intervals(s, track_id) == []
