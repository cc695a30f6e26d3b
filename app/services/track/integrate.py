"""A run joining or leaving its track's aligned data (offset, aggregate), in the caller's
transaction.

``add_run_to_track`` runs when a run's result is stored (inline or by the worker),
``remove_run_from_track`` before a run is deleted, ``realign_track`` rebuilds a track's
alignment and aggregate from its stored runs (``python -m app realign``), ``separate_pending``
redoes the geometry/stiffness separation a worker's stored run left for after its commit (the
run answers done without waiting for it: ~0.8 s of a 1-hour run's storing). All lock the track
first (``SELECT ... FOR NO KEY UPDATE`` where the database has it; SQLite already serialises
writers, and they write before they read the track's data), so two runs of one track stored
at the same time are aligned one after the other, each against the other's data.
"""

from __future__ import annotations

from datetime import datetime
from typing import Literal, cast

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Table, bindparam, case, delete, func, select, update
from sqlalchemy.orm import Session

from app.db.models import Run, Track, TrackProfileChunk, TrackRunLevels
from app.services.storage.profiles import (
    fuse_axles,
    pack_long_level,
    profile_arrays,
    unpack_long_level,
)
from app.services.track.aggregate import (
    CHUNK_POINTS,
    chunked,
    drop_run_levels,
    newest_levels,
    recompute_aggregate,
    store_run_levels,
    unchunked,
)
from app.services.track.alignment import (
    MAX_SHIFT_M,
    RunAlignment,
    align_to_track,
    on_track_grid,
    sample_at,
)
from app.services.track.separation_store import (
    clear_pending,
    pending_chunks,
    recompute_all,
    recompute_stiffness,
)
from engine.accumulate import align_to_others, pass_noise
from engine.chainage import GRID_STEP_M


def lock_track(session: Session, track_id: int) -> None:
    """Serialise the writers of one track's aligned data until the caller's transaction ends.

    Call it before reading anything the change depends on (which chunks a run covers, the
    aggregate to align against): a delete that read a run's chunks before a concurrent store
    had committed them recomputed nothing and left the deleted run in the aggregate.
    """
    if session.get_bind().dialect.name == "sqlite":
        # SQLite has no row locks and pysqlite begins a transaction only at the first write,
        # so reads before it see an older state: a no-op write takes the database's write
        # lock now (waiting for a concurrent store to commit) and every read after it in
        # this transaction sees the latest data.
        session.execute(update(Track).where(Track.id == track_id).values(name=Track.name))
        return
    # FOR NO KEY UPDATE (key_share=True), not FOR UPDATE: the caller's transaction already
    # holds FOR KEY SHARE on the track through the foreign keys of the rows it inserted, and
    # so may a concurrent one; FOR UPDATE conflicts with KEY SHARE, so two such transactions
    # would each wait for the other (PostgreSQL: deadlock detected). NO KEY UPDATE still
    # serialises the runs of one track.
    session.execute(select(Track.id).where(Track.id == track_id).with_for_update(key_share=True))


Separation = Literal["now", "later", "caller"]
"""When the track's geometry/stiffness separation is redone over the chunks a run changed: in
the same transaction, by :func:`separate_pending` after it commits (the chunks are marked),
or by the caller (a rebuild of the whole track)."""


def add_run_to_track(
    session: Session,
    run: Run,
    chainage_m: NDArray[np.float64],
    level_mm: NDArray[np.float64],
    force_n: NDArray[np.float64] | None = None,
    *,
    separation: Separation = "now",
    long_mm: NDArray[np.float64] | None = None,
) -> RunAlignment:
    """Align a just-stored run (profile as processed: chainage m, level mm, the wheel force
    under it N, its long level mm: ``engine.track_quality.long_level``) and merge it.

    Sets the run's offset and alignment fields; a reference or aligned run's levels join the
    track's aggregate over the chunks it covers, and the track's geometry/stiffness
    separation is redone there (``app.services.track.separation_store``) as ``separation`` says.
    Call
    after the run's rows are written (so that on SQLite the transaction already holds the
    write lock).
    """
    lock_track(session, run.track_id)
    # A run stored again (a worker retry) first leaves the aggregate it may have joined.
    remove_run_from_track(session, run, lock=False)
    al = align_to_track(session, run.track_id, chainage_m, level_mm)
    run.chainage_offset_m = al.offset_m
    run.alignment_status = al.status
    run.alignment_correlation = al.correlation
    run.alignment_overlap_m = al.overlap_m
    run.alignment_reason = al.reason
    if al.merged:
        i_lo, levels = on_track_grid(chainage_m, level_mm, al.offset_m)
        force = None
        if force_n is not None:
            _, force = on_track_grid(chainage_m, force_n, al.offset_m)
            force = force[: levels.size] if force.size >= levels.size else None
        long = None
        if long_mm is not None:
            long = _on_points(chainage_m, long_mm, al.offset_m, i_lo, levels.size)
        chunks = store_run_levels(session, run.track_id, run.id, i_lo, levels, force, long)
        if chunks is not None:
            recompute_aggregate(session, run.track_id, *chunks)
            moved = realign_placed(session, run.track_id, *chunks)
            if moved is not None:
                chunks = (min(chunks[0], moved[0]), max(chunks[1], moved[1]))
            if separation == "now":
                recompute_stiffness(session, run.track_id, *chunks)
            elif separation == "later":
                _mark_separation_pending(session, run.track_id, *chunks)
    return al


REALIGN_CHUNKS = 8
"""Chunks (2 km) around the middle of a new run's stretch over which the placed runs there are
aligned again: plenty for a clear correlation peak, the cost that of 2 km."""


def realign_placed(session: Session, track_id: int, c_lo: int, c_hi: int) -> tuple[int, int] | None:
    """Align the ``placed`` runs over chunks ``c_lo..c_hi`` again, each against the
    noise-weighted mean of the other runs there (``engine.accumulate.align_to_others``):
    as the track gains passes that mean grows clear enough to place them. A run whose offset
    is now trusted moves (its stored levels shifted) and becomes ``aligned``; the aggregate is
    rebuilt where runs moved. Returns the chunks changed (None: no run moved). The caller
    holds the track's lock.
    """
    mid = (c_lo + c_hi) // 2
    a = max(c_lo, mid - REALIGN_CHUNKS // 2)
    b = min(c_hi, a + REALIGN_CHUNKS - 1)
    lv = TrackRunLevels.__table__
    placed = set(
        session.scalars(
            select(Run.id).where(
                Run.track_id == track_id, Run.alignment_status == "placed",
                Run.id.in_(select(lv.c.run_id).where(lv.c.track_id == track_id,
                                                     lv.c.chunk.between(a, b))),
            )
        )
    )  # fmt: skip
    if not placed:
        return None
    grid, run_ids, levels, _ = newest_levels(session, track_id, a, b)
    if len(run_ids) < 3:
        return None
    weights = 1.0 / pass_noise(levels, float(grid[1] - grid[0]), 40.0) ** 2
    changed: tuple[int, int] | None = None
    for j, rid in enumerate(run_ids):
        if rid not in placed:
            continue
        off, z, ok = align_to_others(grid, levels, weights, j, max_shift_m=MAX_SHIFT_M)
        if not ok:
            continue
        levels[j] = sample_at(grid + off, levels[j], grid)
        span = _shift_stored_levels(session, track_id, rid, off)
        run = session.get(Run, rid)
        assert run is not None
        run.chainage_offset_m = (run.chainage_offset_m or 0.0) + off
        run.alignment_status = "aligned"
        run.alignment_reason = f"aligned later against the other passes (significance {z:.1f})"
        if span is not None:
            lo, hi = (
                span if changed is None else (min(changed[0], span[0]), max(changed[1], span[1]))
            )
            changed = (lo, hi)
    if changed is not None:
        recompute_aggregate(session, track_id, *changed)
    return changed


def _on_points(
    chainage_m: NDArray[np.float64],
    values: NDArray[np.float64],
    offset_m: float,
    i_lo: int,
    n: int,
) -> NDArray[np.float64]:
    """``values`` (on ``chainage_m``, m) shifted by ``offset_m`` onto the ``n`` track-grid
    points from ``i_lo``: the points of the level they are stored with (NaN beyond them)."""
    j, v = on_track_grid(chainage_m, values, offset_m)
    out = np.full(n, np.nan)
    a, b = max(i_lo, j), min(i_lo + n, j + v.size)
    if b > a:
        out[a - i_lo : b - i_lo] = v[a - j : b - j]
    return out


def _kept_long_levels(session: Session, track_id: int) -> dict[int, list[tuple[int, bytes]]]:
    """The track's stored long levels, packed, by run: ``(chunk, blob)`` each."""
    lv = TrackRunLevels.__table__
    out: dict[int, list[tuple[int, bytes]]] = {}
    for rid, chunk, blob in session.execute(
        select(lv.c.run_id, lv.c.chunk, lv.c.long_mm).where(
            lv.c.track_id == track_id, lv.c.long_mm.is_not(None)
        )
    ):
        out.setdefault(int(rid), []).append((int(chunk), bytes(blob)))
    return out


def _long_level_back(
    rows: list[tuple[int, bytes]], offset_m: float, chainage_m: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """A run's kept long level (its ``(chunk, blob)`` rows) back on its chainage as processed
    (m: the track-grid points minus ``offset_m``); None when none is kept."""
    if not rows:
        return None
    c0, c1 = min(r[0] for r in rows), max(r[0] for r in rows)
    long = unchunked(rows, c0, (c1 - c0 + 1) * CHUNK_POINTS, unpack_long_level)
    assert long is not None
    x = (c0 * CHUNK_POINTS + np.arange(long.size, dtype=np.float64)) * GRID_STEP_M
    return sample_at(x - offset_m, long, chainage_m)


def _shift_stored_levels(
    session: Session, track_id: int, run_id: int, offset_m: float
) -> tuple[int, int] | None:
    """Move a run's stored aligned levels, forces and long level by ``offset_m`` along the
    track; the chunks covered before or after (None: it had none)."""
    lv = TrackRunLevels.__table__
    rows = session.execute(
        select(lv.c.chunk, lv.c.levels, lv.c.force_n, lv.c.long_mm).where(lv.c.run_id == run_id)
    ).all()
    if not rows:
        return None
    c0, c1 = min(r[0] for r in rows), max(r[0] for r in rows)
    n = (c1 - c0 + 1) * CHUNK_POINTS
    levels = unchunked(((c, b) for c, b, _, _ in rows), c0, n)
    assert levels is not None  # levels is NOT NULL
    has_force = all(r[2] is not None for r in rows)
    force = unchunked(((c, f) for c, _, f, _ in rows), c0, n) if has_force else None
    long = unchunked(((c, lb) for c, _, _, lb in rows), c0, n, unpack_long_level)
    x = (c0 * CHUNK_POINTS + np.arange(n, dtype=np.float64)) * GRID_STEP_M
    i_lo, new_levels = on_track_grid(x, levels, offset_m)
    new_force = None if force is None else on_track_grid(x, force, offset_m)[1]
    if new_force is not None and new_force.size < new_levels.size:
        new_force = None
    new_long = None if long is None else _on_points(x, long, offset_m, i_lo, new_levels.size)
    drop_run_levels(session, run_id)
    kept = None if new_force is None else new_force[: new_levels.size]
    stored = store_run_levels(session, track_id, run_id, i_lo, new_levels, kept, new_long)
    lo, hi = (c0, c1) if stored is None else (min(c0, stored[0]), max(c1, stored[1]))
    return lo, hi


def _mark_separation_pending(session: Session, track_id: int, c_lo: int, c_hi: int) -> None:
    """Add chunks ``c_lo..c_hi`` to the track's range waiting for :func:`separate_pending`
    (the caller holds the track's lock)."""
    lo, hi = Track.separation_pending_lo, Track.separation_pending_hi
    # (CASE, not LEAST/GREATEST: SQLite has neither, PostgreSQL's min/max are aggregates)
    session.execute(
        update(Track)
        .where(Track.id == track_id)
        .values(
            separation_pending_lo=case((lo.is_not(None) & (lo < c_lo), lo), else_=c_lo),
            separation_pending_hi=case((hi.is_not(None) & (hi > c_hi), hi), else_=c_hi),
        )
    )


def separate_pending(session: Session, track_id: int) -> bool:
    """Redo the separation a stored run left waiting on its track and clear the mark (caller
    commits); False when none was waiting (another worker did it first).

    Takes the track's lock first: a run being stored there meanwhile waits, and its chunks
    are marked again after this clears the mark.
    """
    lock_track(session, track_id)
    pending = pending_chunks(session, track_id)
    if pending is None:
        return False
    recompute_stiffness(session, track_id, *pending)
    clear_pending(session, track_id)
    return True


def tracks_pending_separation(session: Session) -> list[int]:
    """Ids of the tracks with a separation waiting (normally none for more than a moment:
    the worker that stored the run redoes it next; after a crash, any worker's next idle
    look)."""
    return list(
        session.scalars(
            select(Track.id).where(Track.separation_pending_lo.is_not(None)).order_by(Track.id)
        )
    )


def store_long_level(
    session: Session,
    run_id: int,
    processed_at: datetime | None,
    grid_m: NDArray[np.float64],
    long_mm: NDArray[np.float64] | None,
) -> bool:
    """Store the long level a run was answered done without (``Run.long_level_pending``) and
    clear its mark (caller commits).

    ``long_mm`` (mm, None: the run is too short for its band) is on the run's grid as
    processed (``grid_m``, m); it is placed, as :func:`add_run_to_track` places it, on the
    points of the run's kept levels at the run's present offset (a realignment since moved
    them). Takes the track's lock first. False, and nothing written, when the run is not the
    result the level was inverted for any more (deleted, processed again: another
    ``processed_at``) or its level is stored already.
    """
    track_id = session.scalar(select(Run.track_id).where(Run.id == run_id))
    if track_id is None:
        return False
    lock_track(session, track_id)
    run = session.get(Run, run_id, populate_existing=True)  # as it is now, under the lock
    if (
        run is None or run.status != "done" or not run.long_level_pending
        or run.processed_at != processed_at
    ):  # fmt: skip
        return False
    run.long_level_pending = False
    lv = TrackRunLevels.__table__
    rows = session.execute(select(lv.c.chunk, lv.c.levels).where(lv.c.run_id == run_id)).all()
    if long_mm is None or not rows:
        return True  # too short for the band, or not merged into the track: nothing to keep
    c0 = min(r[0] for r in rows)
    levels = unchunked(rows, c0, (max(r[0] for r in rows) - c0 + 1) * CHUNK_POINTS)
    assert levels is not None  # levels is NOT NULL
    finite = np.flatnonzero(np.isfinite(levels))
    if not finite.size:
        return True
    i_lo = c0 * CHUNK_POINTS + int(finite[0])
    placed = _on_points(grid_m, long_mm, run.offset_m, i_lo, int(finite[-1] - finite[0]) + 1)
    parts = chunked(i_lo, placed)[2]
    if parts:
        session.execute(
            update(cast("Table", lv))
            .where(lv.c.run_id == run_id, lv.c.chunk == bindparam("at"))
            .values(long_mm=bindparam("blob")),
            [{"at": c, "blob": pack_long_level(v)} for c, v in parts.items()],
        )
    return True


def runs_pending_long_level(
    session: Session, before: datetime
) -> list[tuple[int, datetime | None]]:
    """``(id, processed_at)`` of the done runs processed before ``before`` whose long level
    is still to be stored: normally none, the worker that stored a run stores its long level
    next; after a stop in between, any worker's idle look."""
    return [
        (int(rid), when)
        for rid, when in session.execute(
            select(Run.id, Run.processed_at)
            .where(Run.long_level_pending, Run.status == "done", Run.processed_at < before)
            .order_by(Run.id)
        )
    ]


def remove_run_from_track(session: Session, run: Run, *, lock: bool = True) -> None:
    """Take a run out of its track's aggregate (before deleting it); no-op if not in it."""
    if lock:
        lock_track(session, run.track_id)
    chunks = drop_run_levels(session, run.id)
    if chunks is not None:
        recompute_aggregate(session, run.track_id, *chunks)
        recompute_stiffness(session, run.track_id, *chunks)


def realign_track(session: Session, track_id: int) -> list[tuple[int, RunAlignment]]:
    """Align every processed run of a track again, oldest recording first, and rebuild its
    aggregate from scratch (caller commits).

    For runs stored before alignment existed (``alignment_status`` NULL) or after the
    alignment settings changed. Returns each run's id and alignment, in the order processed.
    Runs whose detail expired (``app.services.storage.retention``) keep their alignment and their
    aligned levels: there is no profile left to align again.
    """
    lock_track(session, track_id)
    # the long level is kept only on the track grid: taken aside (packed) with the offsets it
    # was placed with, and put back on each run's own chainage as it is aligned again
    kept_long = _kept_long_levels(session, track_id)
    with_detail = select(Run.id).where(Run.track_id == track_id, Run.detail_expired_at.is_(None))
    session.execute(delete(TrackRunLevels).where(TrackRunLevels.run_id.in_(with_detail)))
    session.execute(delete(TrackProfileChunk).where(TrackProfileChunk.track_id == track_id))
    runs = session.scalars(
        select(Run)
        .where(Run.track_id == track_id, Run.status == "done", Run.detail_expired_at.is_(None))
        .order_by(func.coalesce(Run.recorded_at, Run.created_at), Run.id)
    ).all()
    out = []
    for run in runs:
        names = ("chainage_m", "level_mm", "front_force_n", "rear_force_n")
        cols = profile_arrays(session, run.id, columns=names)
        chainage = cols["chainage_m"]
        long = _long_level_back(kept_long.pop(run.id, []), run.offset_m, chainage)
        level, front, rear = (cols[k] for k in names[1:])
        force = fuse_axles(front, rear) if np.isfinite(front).any() else None
        al = add_run_to_track(
            session, run, chainage, level, force, separation="caller", long_mm=long
        )
        out.append((run.id, al))
    # where only runs without detail remain, their kept levels make the aggregate
    lv = TrackRunLevels.__table__
    lo, hi = session.execute(
        select(func.min(lv.c.chunk), func.max(lv.c.chunk)).where(lv.c.track_id == track_id)
    ).one()
    if lo is not None:
        recompute_aggregate(session, track_id, int(lo), int(hi))
    recompute_all(session, track_id)
    clear_pending(session, track_id)
    return out
