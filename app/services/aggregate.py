"""The aggregated track profile: median, spread and count of the aligned runs per grid point.

Each aligned run's level is kept on the track grid (0.25 m, multiples of 0.25 m) in chunks of
:data:`CHUNK_POINTS` points (``track_run_levels``); when a run arrives or is deleted only the
chunks it covers are recomputed (``engine.aggregate.aggregate_levels``) and rewritten in
``track_profile_points``, inside the caller's transaction. Chainage in m, levels in mm.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import delete, func, insert, select
from sqlalchemy.orm import Session

from app.db.models import Track, TrackProfilePoint, TrackRunLevels
from engine.aggregate import AggregateProfile, aggregate_levels
from engine.chainage import GRID_STEP_M
from engine.decimate import minmax_indices

from .packing import pack_f4, unpack_f4
from .window import Window

CHUNK_POINTS = 1000
"""Grid points per stored chunk of a run's aligned levels (250 m)."""

BATCH_CHUNKS = 40
"""Chunks recomputed at once (10 km: 50 runs x 40 000 points stay a few MB)."""

_DTYPE = np.dtype("<f4")
_PLACEHOLDER = {"qmark": "?", "format": "%s", "pyformat": "%s"}


def chunked(
    i_lo: int, values: NDArray[np.float64]
) -> tuple[int, int, dict[int, NDArray[np.float32]]]:
    """Values from grid point ``i_lo`` on cut into float32 chunks of :data:`CHUNK_POINTS`.

    Returns the first and last chunk holding a finite value and the chunks that do (NaN where
    there is none); ``(0, -1, {})`` when no value is finite.
    """
    finite = np.flatnonzero(np.isfinite(values))
    if finite.size == 0:
        return 0, -1, {}
    i_first, i_last = i_lo + int(finite[0]), i_lo + int(finite[-1])
    c_lo, c_hi = i_first // CHUNK_POINTS, i_last // CHUNK_POINTS
    out = {}
    for chunk in range(c_lo, c_hi + 1):
        buf = np.full(CHUNK_POINTS, np.nan, dtype=_DTYPE)
        a = max(chunk * CHUNK_POINTS, i_lo)
        b = min((chunk + 1) * CHUNK_POINTS, i_lo + values.size)
        if b > a:
            buf[a - chunk * CHUNK_POINTS : b - chunk * CHUNK_POINTS] = values[a - i_lo : b - i_lo]
        if np.isfinite(buf).any():
            out[chunk] = buf
    return c_lo, c_hi, out


def store_run_levels(
    session: Session,
    track_id: int,
    run_id: int,
    i_lo: int,
    levels: NDArray[np.float64],
    force_n: NDArray[np.float64] | None = None,
) -> tuple[int, int] | None:
    """Keep a run's aligned levels (mm), and the wheel force under them (N, same points) when
    known, from grid point ``i_lo`` on; the chunks written.

    Returns ``(first_chunk, last_chunk)``, or None when there is no finite level.
    """
    c_lo, c_hi, parts = chunked(i_lo, levels)
    if not parts:
        return None
    forces = chunked(i_lo, force_n)[2] if force_n is not None else {}
    rows = [
        {"run_id": run_id, "chunk": chunk, "track_id": track_id, "levels": pack_f4(buf),
         "force_n": pack_f4(forces[chunk]) if chunk in forces else None}
        for chunk, buf in parts.items()
    ]  # fmt: skip
    session.execute(insert(TrackRunLevels), rows)
    return c_lo, c_hi


def drop_run_levels(session: Session, run_id: int) -> tuple[int, int] | None:
    """Forget a run's aligned levels; the chunks it covered (None when it had none)."""
    t = TrackRunLevels.__table__
    lo, hi = session.execute(
        select(func.min(t.c.chunk), func.max(t.c.chunk)).where(t.c.run_id == run_id)
    ).one()
    if lo is None:
        return None
    session.execute(delete(TrackRunLevels).where(TrackRunLevels.run_id == run_id))
    return int(lo), int(hi)


def _batches(c_lo: int, c_hi: int) -> Iterator[tuple[int, int]]:
    for a in range(c_lo, c_hi + 1, BATCH_CHUNKS):
        yield a, min(c_hi, a + BATCH_CHUNKS - 1)


def expected_points(
    session: Session, track_id: int, a: int, b: int
) -> tuple[NDArray[np.float64], AggregateProfile | None]:
    """What the aggregate of chunks ``a..b`` must hold: the grid (m) and the aggregation of
    the levels of the track's runs there (None: no run there). Read only."""
    t = TrackRunLevels.__table__
    rows = session.execute(
        select(t.c.run_id, t.c.chunk, t.c.levels).where(
            t.c.track_id == track_id, t.c.chunk >= a, t.c.chunk <= b
        )
    ).all()
    i0 = a * CHUNK_POINTS
    n = (b - a + 1) * CHUNK_POINTS
    run_row = {rid: k for k, rid in enumerate(sorted({r[0] for r in rows}))}
    levels = np.full((len(run_row), n), np.nan)
    for rid, chunk, blob in rows:
        at = (chunk - a) * CHUNK_POINTS
        levels[run_row[rid], at : at + CHUNK_POINTS] = unpack_f4(blob)
    grid = (i0 + np.arange(n, dtype=np.float64)) * GRID_STEP_M
    return grid, (aggregate_levels(grid, levels) if rows else None)


def recompute_aggregate(session: Session, track_id: int, c_lo: int, c_hi: int) -> int:
    """Rebuild the aggregated profile of chunks ``c_lo..c_hi`` from the runs' levels.

    Returns the number of grid points with data written.
    """
    written = 0
    for a, b in _batches(c_lo, c_hi):
        grid, agg = expected_points(session, track_id, a, b)
        session.execute(
            delete(TrackProfilePoint).where(
                TrackProfilePoint.track_id == track_id,
                TrackProfilePoint.chainage_m >= grid[0] - 1e-6,
                TrackProfilePoint.chainage_m <= grid[-1] + 1e-6,
            )
        )
        if agg is None:
            continue
        keep = np.flatnonzero(agg.n_runs > 0)
        _insert_points(
            session, track_id, grid[keep], agg.level_mm[keep], agg.spread_mm[keep],
            agg.n_runs[keep],
        )  # fmt: skip
        written += int(keep.size)
    return written


def _insert_points(
    session: Session,
    track_id: int,
    chainage: NDArray[np.float64],
    level: NDArray[np.float64],
    spread: NDArray[np.float64],
    n_runs: NDArray[np.int64],
) -> None:
    if chainage.size == 0:
        return
    conn = session.connection()
    mark = _PLACEHOLDER.get(conn.dialect.paramstyle)
    columns = [chainage.tolist(), level.tolist(), spread.tolist(), n_runs.tolist()]
    if mark is None:
        names = ("track_id", "chainage_m", "level_mm", "spread_mm", "n_runs")
        dict_rows = [
            dict(zip(names, (track_id, *r), strict=True)) for r in zip(*columns, strict=True)
        ]
        conn.execute(insert(TrackProfilePoint), dict_rows)
        return
    sql = (
        f"INSERT INTO {TrackProfilePoint.__tablename__} "
        f"(track_id, chainage_m, level_mm, spread_mm, n_runs) VALUES ({', '.join([mark] * 5)})"
    )
    conn.exec_driver_sql(sql, list(zip([track_id] * chainage.size, *columns, strict=True)))


def read_track_profile(
    session: Session, track_id: int, from_m: float | None = None, to_m: float | None = None
) -> dict[str, list[Any]]:
    """The aggregated profile between two chainages (m, inclusive), by column.

    Columns ``chainage_m`` (m), ``level_mm``, ``spread_mm`` (mm) and ``n_runs``; only grid
    points that at least one aligned run covers.
    """
    t = TrackProfilePoint.__table__
    names = ("chainage_m", "level_mm", "spread_mm", "n_runs")
    stmt = select(*(t.c[k] for k in names)).where(t.c.track_id == track_id)
    if from_m is not None:
        stmt = stmt.where(t.c.chainage_m >= from_m)
    if to_m is not None:
        stmt = stmt.where(t.c.chainage_m <= to_m)
    rows = session.execute(stmt.order_by(t.c.chainage_m)).all()
    if not rows:
        return {k: [] for k in names}
    return {k: list(col) for k, col in zip(names, zip(*rows, strict=True), strict=True)}


def track_profile_extent(session: Session, track_id: int) -> tuple[float | None, float | None]:
    """First and last chainage of the aggregated profile, m (None, None when empty)."""
    t = TrackProfilePoint.__table__
    lo, hi = session.execute(
        select(func.min(t.c.chainage_m), func.max(t.c.chainage_m)).where(t.c.track_id == track_id)
    ).one()
    return lo, hi


def aggregated_profile_view(
    session: Session, track: Track, window: Window, max_points: int | None
) -> dict[str, Any]:
    """A track's aggregated profile in a window, JSON-ready, thinned to ``max_points`` by
    :func:`engine.decimate.minmax_indices` on the level when asked."""
    cols = read_track_profile(session, track.id, window.from_m, window.to_m)
    n = len(cols["chainage_m"])
    decimated = False
    if max_points is not None and n > max_points:
        idx = minmax_indices(np.asarray(cols["level_mm"], dtype=np.float64), max_points)
        cols = {k: [v[i] for i in idx.tolist()] for k, v in cols.items()}
        decimated = True
    return {
        "track_id": track.id,
        "track": track.name,
        "from_m": window.from_m,
        "to_m": window.to_m,
        "grid_step_m": GRID_STEP_M,
        "n": n,
        "decimated": decimated,
        **cols,
    }
