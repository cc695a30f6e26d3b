"""Consistency of stored derived data: a track's aggregated profile is what its runs make.

The aggregate (``track_profile_chunks``) is kept incrementally: each stored, aligned run adds
its levels, each deleted one removes them. :func:`check_aggregate` recomputes it from the
runs' stored levels (read only) and compares, so a run that left data behind (the probe's
delete racing a store) or a missing contribution is found; ``python -m app check-aggregates``
runs it for every track (``--fix`` rebuilds the tracks that differ).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.db.models import Run, TrackRunLevels
from app.services.track.aggregate import (
    CHUNK_POINTS,
    _batches,
    aggregate_chunk_range,
    expected_points,
    read_aggregate,
    recompute_aggregate,
)

LEVEL_TOLERANCE_MM = 1e-3
"""Largest difference between a stored and a recomputed aggregate level, mm (float32)."""


@dataclass(frozen=True)
class AggregateCheck:
    """How a track's stored aggregate compares with the one its runs make.

    Attributes
    ----------
    track_id : int
    stored_points, expected_points : int
        Grid points with data, stored and recomputed.
    differing_points : int
        Points missing, extra, or with another level or run count.
    orphan_runs : list of int
        Runs with stored levels that are not processed runs of the track (deleted, failed).
    chunks : tuple of (int, int) or None
        Chunk range compared (None: the track has no aggregate and no levels).
    """

    track_id: int
    stored_points: int
    expected_points: int
    differing_points: int
    orphan_runs: list[int]
    chunks: tuple[int, int] | None

    @property
    def ok(self) -> bool:
        """True when the aggregate is exactly what the runs make."""
        return self.differing_points == 0 and not self.orphan_runs


def _chunk_range(session: Session, track_id: int) -> tuple[int, int] | None:
    lv = TrackRunLevels.__table__
    c_lo, c_hi = session.execute(
        select(func.min(lv.c.chunk), func.max(lv.c.chunk)).where(lv.c.track_id == track_id)
    ).one()
    levels = None if c_lo is None else (int(c_lo), int(c_hi))
    ranges = [r for r in (levels, aggregate_chunk_range(session, track_id)) if r is not None]
    return (min(r[0] for r in ranges), max(r[1] for r in ranges)) if ranges else None


def check_aggregate(session: Session, track_id: int) -> AggregateCheck:
    """Compare a track's stored aggregate with the one its runs' levels make (read only)."""
    lv = TrackRunLevels.__table__
    with_levels = set(session.scalars(select(lv.c.run_id).where(lv.c.track_id == track_id)))
    done = set(session.scalars(select(Run.id).where(Run.track_id == track_id,
                                                    Run.status == "done")))  # fmt: skip
    orphans = sorted(with_levels - done)
    chunks = _chunk_range(session, track_id)
    stored_n = expected_n = differing = 0
    if chunks is not None:
        for a, b in _batches(*chunks):
            grid, agg = expected_points(session, track_id, a, b)
            stored = read_aggregate(session, track_id, a * CHUNK_POINTS, (b + 1) * CHUNK_POINTS - 1)
            n_want = np.zeros(grid.size, dtype=np.int64) if agg is None else agg.n_runs
            level_want = np.full(grid.size, np.nan) if agg is None else agg.level_mm
            stored_n += int(np.count_nonzero(stored.n_runs))
            expected_n += int(np.count_nonzero(n_want))
            both = (stored.n_runs > 0) & (n_want > 0)
            close = np.abs(stored.level_mm - level_want) <= LEVEL_TOLERANCE_MM
            bad = (stored.n_runs != n_want) | (both & ~close)
            differing += int(np.count_nonzero(bad))
    return AggregateCheck(track_id, stored_n, expected_n, differing, orphans, chunks)


def rebuild_aggregate(session: Session, track_id: int) -> None:
    """Recompute a track's whole aggregate from its runs' levels (caller commits)."""
    from app.services.track.integrate import lock_track

    lock_track(session, track_id)
    chunks = _chunk_range(session, track_id)
    if chunks is not None:
        recompute_aggregate(session, track_id, *chunks)
