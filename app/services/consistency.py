"""Consistency of stored derived data: a track's aggregated profile is what its runs make.

The aggregate (``track_profile_points``) is kept incrementally: each stored, aligned run adds
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

from app.db.models import Run, TrackProfilePoint, TrackRunLevels
from engine.chainage import GRID_STEP_M

from .aggregate import CHUNK_POINTS, _batches, expected_points, recompute_aggregate

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
    x_lo, x_hi = session.execute(
        select(func.min(TrackProfilePoint.chainage_m), func.max(TrackProfilePoint.chainage_m))
        .where(TrackProfilePoint.track_id == track_id)
    ).one()  # fmt: skip
    los = [v for v in (c_lo, None if x_lo is None else int(x_lo / GRID_STEP_M) // CHUNK_POINTS)
           if v is not None]  # fmt: skip
    his = [v for v in (c_hi, None if x_hi is None else int(x_hi / GRID_STEP_M) // CHUNK_POINTS)
           if v is not None]  # fmt: skip
    return (min(los), max(his)) if los else None


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
            rows = session.execute(
                select(TrackProfilePoint.chainage_m, TrackProfilePoint.level_mm,
                       TrackProfilePoint.n_runs)
                .where(TrackProfilePoint.track_id == track_id,
                       TrackProfilePoint.chainage_m >= grid[0] - 1e-6,
                       TrackProfilePoint.chainage_m <= grid[-1] + 1e-6)
            ).all()  # fmt: skip
            stored = {int(round(c / GRID_STEP_M)): (lvl, n) for c, lvl, n in rows}
            expected: dict[int, tuple[float, int]] = {}
            if agg is not None:
                for k in np.flatnonzero(agg.n_runs > 0).tolist():
                    i = int(round(grid[k] / GRID_STEP_M))
                    expected[i] = (float(agg.level_mm[k]), int(agg.n_runs[k]))
            stored_n += len(stored)
            expected_n += len(expected)
            for i in stored.keys() | expected.keys():
                s, e = stored.get(i), expected.get(i)
                if (
                    s is None
                    or e is None
                    or s[1] != e[1]
                    or not abs(s[0] - e[0]) <= LEVEL_TOLERANCE_MM
                ):
                    differing += 1
    return AggregateCheck(track_id, stored_n, expected_n, differing, orphans, chunks)


def rebuild_aggregate(session: Session, track_id: int) -> None:
    """Recompute a track's whole aggregate from its runs' levels (caller commits)."""
    from .integrate import lock_track

    lock_track(session, track_id)
    chunks = _chunk_range(session, track_id)
    if chunks is not None:
        recompute_aggregate(session, track_id, *chunks)
