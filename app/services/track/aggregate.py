"""The aggregated track profile: median, spread and count of the aligned runs per grid point.

Each aligned run's level is kept on the track grid (0.25 m, multiples of 0.25 m) in chunks of
:data:`CHUNK_POINTS` points (``track_run_levels``); when a run arrives or is deleted only the
chunks it covers are recomputed (``engine.aggregate.aggregate_levels``) and rewritten in
``track_profile_chunks`` (the same chunks, one packed row each), inside the caller's
transaction. A chunk's aggregate is made of its :data:`NEWEST_PASSES` newest runs
(:func:`newest_runs`), as is the geometry/stiffness separation
(``app.services.track.separation_store``).
The soft spots of the same runs combined (``engine.accumulate.detect_on_aggregate``) are
found then too and kept with the chunk their deepest point lies in (:func:`store_combined_spots`),
so the register reads them instead of detecting on every request.
Chainage in m, levels in mm.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import asdict, dataclass
from functools import lru_cache
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Select, Subquery, delete, func, insert, select, update
from sqlalchemy.orm import Session

from app.db.models import Run, Track, TrackProfileChunk, TrackRunLevels
from app.services.storage.packing import (
    pack_f4,
    pack_named,
    unpack_f4,
    unpack_f4_kept,
    unpack_named,
)
from app.services.storage.profiles import pack_long_level
from app.services.views.window import Window
from engine.accumulate import ResidualCache, detect_on_aggregate
from engine.aggregate import AggregateProfile, aggregate_levels
from engine.chainage import GRID_STEP_M
from engine.decimate import minmax_indices
from engine.errors import EngineError

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

log = logging.getLogger(__name__)


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


def unchunked_by_run(
    rows: Iterable[tuple[int, int, bytes | None]],
    c_lo: int,
    n: int,
    unpack: Callable[[bytes], NDArray[np.floating[Any]]] = unpack_f4,
    dtype: type[np.floating[Any]] = np.float64,
) -> dict[int, NDArray[np.floating[Any]]]:
    """The inverse of :func:`chunked` for stored rows ``(run id, chunk, blob)``: each run's
    chunks unpacked (``unpack``) onto ``n`` grid points from chunk ``c_lo``'s first, NaN
    where it has none; NULL blobs are skipped, a run with none is left out."""
    out: dict[int, NDArray[np.floating[Any]]] = {}
    for rid, chunk, blob in rows:
        at = (int(chunk) - c_lo) * CHUNK_POINTS
        if blob is None or not 0 <= at < n:
            continue
        arr = out.get(int(rid))
        if arr is None:
            arr = out[int(rid)] = np.full(n, np.nan, dtype=dtype)
        part = unpack(bytes(blob))
        arr[at : at + part.size] = part[: n - at]
    return out


def unchunked(
    rows: Iterable[tuple[int, bytes | None]],
    c_lo: int,
    n: int,
    unpack: Callable[[bytes], NDArray[np.floating[Any]]] = unpack_f4,
) -> NDArray[np.float64] | None:
    """One run's stored chunks ``(chunk, blob)`` unpacked as :func:`unchunked_by_run` does;
    None when it has no blob."""
    one = unchunked_by_run(((0, c, b) for c, b in rows), c_lo, n, unpack)
    return cast("NDArray[np.float64] | None", one.get(0))


def store_run_levels(
    session: Session,
    track_id: int,
    run_id: int,
    i_lo: int,
    levels: NDArray[np.float64],
    force_n: NDArray[np.float64] | None = None,
    long_mm: NDArray[np.float64] | None = None,
) -> tuple[int, int] | None:
    """Keep a run's aligned levels (mm), and the wheel force under them (N, same points) and
    its long level (mm, same points: ``engine.track_quality.long_level``) when known, from
    grid point ``i_lo`` on; the chunks written.

    Returns ``(first_chunk, last_chunk)``, or None when there is no finite level.
    """
    c_lo, c_hi, parts = chunked(i_lo, levels)
    if not parts:
        return None
    forces = chunked(i_lo, force_n)[2] if force_n is not None else {}
    longs = chunked(i_lo, long_mm)[2] if long_mm is not None else {}
    rows = [
        {"run_id": run_id, "chunk": chunk, "track_id": track_id, "levels": pack_f4(buf),
         "force_n": pack_f4(forces[chunk]) if chunk in forces else None,
         "long_mm": pack_long_level(longs[chunk]) if chunk in longs else None}
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
    return _newest_runs(track_id, c_lo, c_hi, with_force, NEWEST_PASSES)


@lru_cache(maxsize=256)
def _newest_runs(track_id: int, c_lo: int, c_hi: int, with_force: bool, newest: int) -> Subquery:
    # Built once per stretch: a pass re-reads the same chunks for its aggregate and each
    # detection unit, and building the statement costs about as much as running it.
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
    return select(keys.c.run_id, keys.c.chunk).where(keys.c.rank <= newest).subquery()


@lru_cache(maxsize=256)
def _levels_query(track_id: int, a: int, b: int, with_force: bool, newest: int) -> Select[Any]:
    """The statement :func:`newest_levels` runs (built once per stretch, as its keys)."""
    t = TrackRunLevels.__table__
    keys = _newest_runs(track_id, a, b, False, newest)
    cols = [t.c.run_id, t.c.chunk, t.c.levels] + ([t.c.force_n] if with_force else [])
    return select(*cols).join(keys, (keys.c.run_id == t.c.run_id) & (keys.c.chunk == t.c.chunk))


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
    rows = session.execute(_levels_query(track_id, a, b, with_force, NEWEST_PASSES)).all()
    i0 = a * CHUNK_POINTS
    n = (b - a + 1) * CHUNK_POINTS
    run_ids = sorted({r[0] for r in rows})
    run_row = {rid: k for k, rid in enumerate(run_ids)}
    levels = np.full((len(run_row), n), np.nan)
    forces = np.full((len(run_row), n), np.nan) if with_force else None
    for row in rows:
        rid, chunk, blob = row[0], row[1], row[2]
        at = (chunk - a) * CHUNK_POINTS
        levels[run_row[rid], at : at + CHUNK_POINTS] = unpack_f4_kept(blob)
        if forces is not None and row[3] is not None:
            forces[run_row[rid], at : at + CHUNK_POINTS] = unpack_f4_kept(row[3])
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
    store_combined_spots(session, track_id, c_lo, c_hi)
    return written


DETECTION_CHUNKS = 4
"""Chunks searched together for the combined passes' soft spots (1 km): the stretch whose
measured noise and roughness set the threshold, and what a run arriving makes detect again
(every unit within :data:`DETECTION_MARGIN_CHUNKS` of the chunks it changed)."""

DETECTION_MARGIN_CHUNKS = 1
"""Chunks of context read either side of a detection unit (250 m: far more than the 40 m
baseline and any zone); a spot belongs to the unit its deepest point lies in."""

_RESIDUALS = ResidualCache()
"""The passes' residuals of the units detected last in this process: a pass arriving changes
one row of a unit, the others are filtered once, not at every pass."""


@dataclass(frozen=True)
class CombinedSpot:
    """A soft spot of the combined passes, as kept with its chunk.

    Attributes
    ----------
    start_m, end_m, peak_m : float
        Extent and deepest point on the track's chainage, m.
    depth_mm : float
        Depth of the combined level there, mm.
    loss_pct : float or None
        Fitted stiffness loss, % (None: no figure).
    significance : float
        Depth over the combination's measured noise there.
    supporting, covering : tuple of int
        Run ids that cover the spot and dip there themselves; run ids that cover it.
    """

    start_m: float
    end_m: float
    peak_m: float
    depth_mm: float
    loss_pct: float | None
    significance: float
    supporting: tuple[int, ...]
    covering: tuple[int, ...]

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict (``track_profile_chunks.spots`` entries; a number that is not
        finite is null, as strict JSON wants)."""
        out = {k: v if not isinstance(v, float) or math.isfinite(v) else None
               for k, v in asdict(self).items()}  # fmt: skip
        out["supporting"], out["covering"] = list(self.supporting), list(self.covering)
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> CombinedSpot:
        """Inverse of :meth:`to_json` (a null measure back to NaN, the loss stays None)."""
        nums = {k: math.nan if d[k] is None else float(d[k])
                for k in ("start_m", "end_m", "peak_m", "depth_mm", "significance")}  # fmt: skip
        return cls(**nums, loss_pct=d["loss_pct"], supporting=tuple(d["supporting"]),
                   covering=tuple(d["covering"]))  # fmt: skip


def _chunk_of(chainage_m: float) -> int:
    return math.floor(chainage_m / GRID_STEP_M) // CHUNK_POINTS


def detect_combined(session: Session, track_id: int, unit: int) -> dict[int, list[CombinedSpot]]:
    """The soft spots of detection unit ``unit`` (chunks ``unit * DETECTION_CHUNKS`` on) found
    on the combination of each chunk's newest runs, with the margin either side as context;
    by the chunk of their deepest point. Only spots at least two runs cover. Read only."""
    a = unit * DETECTION_CHUNKS
    b = a + DETECTION_CHUNKS - 1
    lo, hi = a - DETECTION_MARGIN_CHUNKS, b + DETECTION_MARGIN_CHUNKS
    grid, run_ids, levels, forces = newest_levels(session, track_id, lo, hi, with_force=True)
    out: dict[int, list[CombinedSpot]] = {}
    if len(run_ids) < 2 or not (np.isfinite(levels).sum(axis=0) >= 2).any():
        return out
    keep = np.flatnonzero(np.isfinite(levels).any(axis=0))
    sl = slice(int(keep[0]), int(keep[-1]) + 1)
    load = (
        float(np.nanmean(forces[:, sl]))
        if forces is not None and np.isfinite(forces[:, sl]).any()
        else None
    )
    unit_m = (a * CHUNK_POINTS * GRID_STEP_M, (b + 1) * CHUNK_POINTS * GRID_STEP_M)
    det = detect_on_aggregate(
        grid[sl], levels[:, sl], load_n=load, peaks_in_m=unit_m, cache=_RESIDUALS
    )
    for spot in det.spots:
        chunk = _chunk_of(spot.peak_m)
        if not (a <= chunk <= b) or len(spot.covering) < 2:
            continue
        loss = spot.stiffness_loss_pct if math.isfinite(spot.stiffness_loss_pct) else None
        out.setdefault(chunk, []).append(
            CombinedSpot(spot.start_m, spot.end_m, spot.peak_m, spot.depth_mm, loss,
                         spot.significance, tuple(run_ids[j] for j in spot.supporting),
                         tuple(run_ids[j] for j in spot.covering))
        )  # fmt: skip
    return out


def _units_near(c_lo: int, c_hi: int) -> range:
    """Detection units whose chunks or margin reach chunks ``c_lo..c_hi``."""
    return range(
        (c_lo - DETECTION_MARGIN_CHUNKS) // DETECTION_CHUNKS,
        (c_hi + DETECTION_MARGIN_CHUNKS) // DETECTION_CHUNKS + 1,
    )


def store_combined_spots(session: Session, track_id: int, c_lo: int, c_hi: int) -> None:
    """Detect again on every unit the changed chunks ``c_lo..c_hi`` reach and keep the spots
    with the stored aggregate chunks (an empty list where a chunk has none)."""
    t = TrackProfileChunk.__table__
    for unit in _units_near(c_lo, c_hi):
        a = unit * DETECTION_CHUNKS
        chunks = session.scalars(
            select(t.c.chunk).where(
                t.c.track_id == track_id, t.c.chunk.between(a, a + DETECTION_CHUNKS - 1)
            )
        ).all()
        if not chunks:
            continue
        try:
            found: dict[int, list[CombinedSpot]] | None = detect_combined(session, track_id, unit)
        except EngineError as exc:
            # The run is stored whatever the combined detection says: its chunks keep no spots
            # (NULL) and are detected on when read.
            log.warning("combined detection of track %s unit %s failed: %s", track_id, unit, exc)
            found = None
        session.execute(
            update(TrackProfileChunk),
            [
                {"track_id": track_id, "chunk": c,
                 "spots": None if found is None else [s.to_json() for s in found.get(c, [])]}
                for c in chunks
            ],
        )  # fmt: skip


def read_combined_spots(session: Session, track_id: int) -> list[CombinedSpot]:
    """The track's combined-pass soft spots as kept with its chunks, by chainage; a unit with
    a chunk stored before they were kept is detected on here (not stored: a read)."""
    t = TrackProfileChunk.__table__
    rows = session.execute(
        select(t.c.chunk, t.c.spots).where(t.c.track_id == track_id).order_by(t.c.chunk)
    ).all()
    stale = {chunk // DETECTION_CHUNKS for chunk, spots in rows if spots is None}
    out = [
        CombinedSpot.from_json(d)
        for chunk, spots in rows
        if chunk // DETECTION_CHUNKS not in stale
        for d in spots or ()
    ]
    for unit in sorted(stale):
        for spots in detect_combined(session, track_id, unit).values():
            out.extend(spots)
    return sorted(out, key=lambda s: s.peak_m)


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
