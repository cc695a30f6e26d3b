"""The aggregated track profile: median, spread and count of the aligned runs per grid point.

Each aligned run's level is kept on the track grid (0.25 m, multiples of 0.25 m) in chunks of
:data:`CHUNK_POINTS` points (``track_run_levels``); when a run arrives or is deleted only the
chunks it covers are recomputed (``engine.aggregate.aggregate_levels``) and rewritten in
``track_profile_chunks`` (the same chunks, one packed row each), inside the caller's
transaction. A chunk's aggregate is made of its :data:`NEWEST_PASSES` newest runs
(:func:`newest_runs`), as is the geometry/stiffness separation (``app.services.stiffness``).
Chainage in m, levels in mm.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Subquery, delete, func, insert, select
from sqlalchemy.orm import Session

from app.db.models import Run, Track, TrackProfileChunk, TrackRunLevels
from engine.aggregate import AggregateProfile, aggregate_levels
from engine.chainage import GRID_STEP_M
from engine.decimate import minmax_indices

from .packing import pack_f4, pack_named, unpack_f4, unpack_named
from .window import Window

CHUNK_POINTS = 1000
"""Grid points per stored chunk of a run's aligned levels (250 m)."""

BATCH_CHUNKS = 40
"""Chunks recomputed at once (10 km: 50 runs x 40 000 points stay a few MB)."""

NEWEST_PASSES = 50
"""Runs per chunk that make its aggregate and its geometry/stiffness separation: the newest by
recording time (then the newest stored). Without a cap every stored run would re-read and
recompute every earlier run over its stretch, a cost that grows without end for a fleet that
passes a kilometre ~40 times a day (``benchmarks/bench_year.py``). Fifty passes of different
loads are more than the separation needs, and the aggregate stays the track's present state,
not its history; older runs' aligned levels stay stored (realignment, the register), and
enter again when newer ones are deleted."""

AGGREGATE_COLUMNS = ("level_mm", "spread_mm", "n_runs")
"""What a stored chunk of the aggregate holds per grid point (:func:`pack_chunk`)."""

_DTYPE = np.dtype("<f4")


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


def newest_runs(track_id: int, c_lo: int, c_hi: int, *, with_force: bool = False) -> Subquery:
    """The ``(run_id, chunk)`` keys of chunks ``c_lo..c_hi`` that make each chunk's aggregate:
    its :data:`NEWEST_PASSES` newest runs by recording time (a run without
    one last), then by id; ``with_force``: only runs that kept the wheel force. A subquery
    (columns ``run_id``, ``chunk``) to join ``track_run_levels`` on; the ranking reads keys
    and recording times only, not the levels."""
    t = TrackRunLevels.__table__
    rank = func.row_number().over(
        partition_by=t.c.chunk,
        order_by=(Run.recorded_at.desc().nulls_last(), t.c.run_id.desc()),
    )
    ranked = select(t.c.run_id, t.c.chunk, rank.label("rank")).join(Run, Run.id == t.c.run_id)
    ranked = ranked.where(t.c.track_id == track_id, t.c.chunk >= c_lo, t.c.chunk <= c_hi)
    if with_force:
        ranked = ranked.where(t.c.force_n.is_not(None))
    keys = ranked.subquery()
    return select(keys.c.run_id, keys.c.chunk).where(keys.c.rank <= NEWEST_PASSES).subquery()


def expected_points(
    session: Session, track_id: int, a: int, b: int
) -> tuple[NDArray[np.float64], AggregateProfile | None]:
    """What the aggregate of chunks ``a..b`` must hold: the grid (m) and the aggregation of
    the levels of each chunk's newest runs (:func:`newest_runs`; None: no run there). Read
    only."""
    grid, run_ids, levels, _ = newest_levels(session, track_id, a, b)
    return grid, (aggregate_levels(grid, levels) if run_ids else None)


def newest_levels(
    session: Session, track_id: int, a: int, b: int, *, with_force: bool = False
) -> tuple[NDArray[np.float64], list[int], NDArray[np.float64], NDArray[np.float64] | None]:
    """The aligned levels of the runs that make chunks ``a..b``'s aggregate
    (:func:`newest_runs`): the grid (m), the run ids (ascending), their levels (runs x points,
    mm, NaN where a run has none) and, with ``with_force``, the wheel force under them (N,
    NaN where not kept). Read only."""
    t = TrackRunLevels.__table__
    keys = newest_runs(track_id, a, b)
    cols = [t.c.run_id, t.c.chunk, t.c.levels] + ([t.c.force_n] if with_force else [])
    rows = session.execute(
        select(*cols).join(keys, (keys.c.run_id == t.c.run_id) & (keys.c.chunk == t.c.chunk))
    ).all()
    i0 = a * CHUNK_POINTS
    n = (b - a + 1) * CHUNK_POINTS
    run_ids = sorted({r[0] for r in rows})
    run_row = {rid: k for k, rid in enumerate(run_ids)}
    levels = np.full((len(run_row), n), np.nan)
    forces = np.full((len(run_row), n), np.nan) if with_force else None
    for row in rows:
        rid, chunk, blob = row[0], row[1], row[2]
        at = (chunk - a) * CHUNK_POINTS
        levels[run_row[rid], at : at + CHUNK_POINTS] = unpack_f4(blob)
        if forces is not None and row[3] is not None:
            forces[run_row[rid], at : at + CHUNK_POINTS] = unpack_f4(row[3])
    grid = (i0 + np.arange(n, dtype=np.float64)) * GRID_STEP_M
    return grid, run_ids, levels, forces


def pack_chunk(
    level_mm: NDArray[np.float64], spread_mm: NDArray[np.float64], n_runs: NDArray[np.int64]
) -> bytes:
    """A chunk of the aggregate packed for ``track_profile_chunks.data``: level and spread
    (mm) and run count per grid point, float64 (the median of float32 levels is exact in
    float64: the stored aggregate is what the engine computed), compressed."""
    cols = {"level_mm": level_mm, "spread_mm": spread_mm, "n_runs": n_runs.astype(np.float64)}
    return pack_named(cols, AGGREGATE_COLUMNS)


def unpack_chunk(
    blob: bytes,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Inverse of :func:`pack_chunk`: level (mm), spread (mm), run count."""
    cols = unpack_named(bytes(blob), AGGREGATE_COLUMNS)
    return cols["level_mm"], cols["spread_mm"], cols["n_runs"].astype(np.int64)


def recompute_aggregate(session: Session, track_id: int, c_lo: int, c_hi: int) -> int:
    """Rebuild the aggregated profile of chunks ``c_lo..c_hi`` from the runs' levels.

    Returns the number of grid points with data written.
    """
    t = TrackProfileChunk.__table__
    written = 0
    for a, b in _batches(c_lo, c_hi):
        _, agg = expected_points(session, track_id, a, b)
        session.execute(
            delete(TrackProfileChunk).where(t.c.track_id == track_id, t.c.chunk.between(a, b))
        )
        if agg is None:
            continue
        rows = []
        for chunk in range(a, b + 1):
            part = slice((chunk - a) * CHUNK_POINTS, (chunk - a + 1) * CHUNK_POINTS)
            n = agg.n_runs[part]
            covered = int(np.count_nonzero(n))
            if covered:
                data = pack_chunk(agg.level_mm[part], agg.spread_mm[part], n)
                rows.append({"track_id": track_id, "chunk": chunk, "data": data})
                written += covered
        if rows:
            session.execute(insert(TrackProfileChunk), rows)
    return written


@dataclass(frozen=True)
class AggregateSpan:
    """The stored aggregate over consecutive grid points ``i_lo ...`` (chainage =
    index x :data:`~engine.chainage.GRID_STEP_M`): level and spread in mm (NaN and
    ``n_runs`` 0 where no run covers a point)."""

    i_lo: int
    level_mm: NDArray[np.float64]
    spread_mm: NDArray[np.float64]
    n_runs: NDArray[np.int64]

    def chainage_m(self) -> NDArray[np.float64]:
        """Chainage of each point, m."""
        return (self.i_lo + np.arange(self.n_runs.size, dtype=np.float64)) * GRID_STEP_M


def read_aggregate(session: Session, track_id: int, i_lo: int, i_hi: int) -> AggregateSpan:
    """The stored aggregate at grid points ``i_lo..i_hi`` (inclusive): one range scan over the
    chunks holding them."""
    t = TrackProfileChunk.__table__
    n = max(0, i_hi - i_lo + 1)
    span = AggregateSpan(i_lo, np.full(n, np.nan), np.full(n, np.nan), np.zeros(n, dtype=np.int64))
    if n == 0:
        return span
    rows = session.execute(
        select(t.c.chunk, t.c.data).where(
            t.c.track_id == track_id,
            t.c.chunk >= i_lo // CHUNK_POINTS,
            t.c.chunk <= i_hi // CHUNK_POINTS,
        )
    ).all()
    for chunk, blob in rows:
        first = chunk * CHUNK_POINTS
        a, b = max(first, i_lo), min(first + CHUNK_POINTS, i_hi + 1)
        level, spread, count = unpack_chunk(blob)
        span.level_mm[a - i_lo : b - i_lo] = level[a - first : b - first]
        span.spread_mm[a - i_lo : b - i_lo] = spread[a - first : b - first]
        span.n_runs[a - i_lo : b - i_lo] = count[a - first : b - first]
    return span


def aggregate_chunk_range(session: Session, track_id: int) -> tuple[int, int] | None:
    """First and last stored chunk of a track's aggregate (None: it has none)."""
    t = TrackProfileChunk.__table__
    lo, hi = session.execute(
        select(func.min(t.c.chunk), func.max(t.c.chunk)).where(t.c.track_id == track_id)
    ).one()
    return None if lo is None else (int(lo), int(hi))


def read_aggregate_grid(
    session: Session, track_id: int, i_lo: int, i_hi: int
) -> NDArray[np.float64]:
    """The track's aggregated level at grid points ``i_lo..i_hi`` (mm; NaN where no run)."""
    return read_aggregate(session, track_id, i_lo, i_hi).level_mm


def read_track_profile(
    session: Session, track_id: int, from_m: float | None = None, to_m: float | None = None
) -> dict[str, list[Any]]:
    """The aggregated profile between two chainages (m, inclusive), by column.

    Columns ``chainage_m`` (m), ``level_mm``, ``spread_mm`` (mm) and ``n_runs``; only grid
    points that at least one aligned run covers.
    """
    names = ("chainage_m", "level_mm", "spread_mm", "n_runs")
    stored = aggregate_chunk_range(session, track_id)
    if stored is None:
        return {k: [] for k in names}
    i_lo, i_hi = stored[0] * CHUNK_POINTS, (stored[1] + 1) * CHUNK_POINTS - 1
    if from_m is not None:
        i_lo = max(i_lo, math.ceil(from_m / GRID_STEP_M))
    if to_m is not None:
        i_hi = min(i_hi, math.floor(to_m / GRID_STEP_M))
    span = read_aggregate(session, track_id, i_lo, i_hi)
    keep = np.flatnonzero(span.n_runs > 0)
    return {
        "chainage_m": span.chainage_m()[keep].tolist(),
        "level_mm": span.level_mm[keep].tolist(),
        "spread_mm": span.spread_mm[keep].tolist(),
        "n_runs": span.n_runs[keep].tolist(),
    }


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
