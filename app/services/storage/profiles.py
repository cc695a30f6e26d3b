"""Writing and reading a run's profile: compressed blocks of 1 km of its chainage grid.

A run's profile lives on the engine's 0.25 m grid (chainage = grid index x 0.25 m, as
processed). Block ``b`` of a run holds its grid points ``b * BLOCK_POINTS`` to
``(b + 1) * BLOCK_POINTS - 1`` (``app.db.models.RunProfileBlock``), the columns packed by
``app.services.storage.packing``: levels rounded to 0.0001 mm, wheel forces to 1 N. The fused level
is
not stored: it is the engine's :func:`~engine.pipeline.fuse_axles` of the axles' levels. A window
read is one range scan of the ``(run_id, block)`` key; a 2 km window touches three rows.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import delete, insert, select
from sqlalchemy.orm import Session

from app.db.models import RunProfileBlock
from app.services.storage.packing import (
    FORCE_RESOLUTION_N,
    LEVEL_RESOLUTION_MM,
    decode_block,
    encode_block,
)
from engine.chainage import GRID_STEP_M
from engine.pipeline import fuse_axles

PROFILE_COLUMNS = (
    "chainage_m", "level_mm", "front_level_mm", "rear_level_mm", "baseline_mm",
    "front_force_n", "rear_force_n",
)  # fmt: skip
STORED_COLUMNS = (
    "front_level_mm", "rear_level_mm", "baseline_mm", "front_force_n", "rear_force_n",
)  # fmt: skip
"""What a block holds, in order (chainage is the grid index, the level fused from the axles')."""

SCALES = tuple(
    FORCE_RESOLUTION_N if c.endswith("_n") else LEVEL_RESOLUTION_MM for c in STORED_COLUMNS
)

BLOCK_POINTS = 4000
"""Grid points per stored block (1 km at 0.25 m)."""

_GRID_TOL = 1e-6  # m: a chainage this close to a grid point is on it

LONG_LEVEL_RESOLUTION_MM = 0.001
"""Resolution the long level (``engine.track_quality.long_level``) is kept at, mm: its
rounding adds 0.0003 mm RMS, three hundredths of D2's 0.1 mm, for 6 kB per run-km instead of
the 13 kB of lossless float32 (docs/benchmarks.md)."""


def pack_long_level(values_mm: NDArray[np.floating]) -> bytes:
    """The long level of a stretch (mm, NaN = none) packed at :data:`LONG_LEVEL_RESOLUTION_MM`
    (``track_run_levels.long_mm``)."""
    return encode_block([np.asarray(values_mm, dtype=np.float64)], (LONG_LEVEL_RESOLUTION_MM,))


def unpack_long_level(blob: bytes) -> NDArray[np.float64]:
    """Inverse of :func:`pack_long_level`, mm (NaN = none)."""
    return decode_block(blob, (LONG_LEVEL_RESOLUTION_MM,))[0]


def nullable(a: NDArray[np.float64]) -> list[float | None]:
    """Values as a list with None where there is no data (NaN, inf): JSON null, SQL NULL."""
    # NaN means "no data here" (an axle that did not pass): stored as NULL on every database.
    values: list[float | None] = a.tolist()
    bad = np.flatnonzero(~np.isfinite(a))
    for i in bad:
        values[i] = None
    return values


def finite_or_none(value: Any) -> float | None:
    """One value as :func:`nullable` keeps it: a float, or None for NaN, infinities and what
    is not a number."""
    try:
        f = float(value)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def grid_index(chainage_m: NDArray[np.float64]) -> int:
    """Grid index of a profile's first point; the chainage must be the 0.25 m grid, in order.

    Raises
    ------
    ValueError
        The chainage is not consecutive points of the grid (the engine always gives them).
    """
    if chainage_m.size == 0:
        return 0
    k = np.rint(chainage_m / GRID_STEP_M)
    if np.abs(k * GRID_STEP_M - chainage_m).max() > _GRID_TOL or (
        chainage_m.size > 1 and not np.all(np.diff(k) == 1)
    ):
        raise ValueError(f"a stored profile must be consecutive points of the {GRID_STEP_M} m grid")
    return int(k[0])


def encode_profile(
    chainage_m: NDArray[np.float64], columns: list[NDArray[np.float64]]
) -> list[tuple[int, int, bytes]]:
    """A profile (chainage m; :data:`STORED_COLUMNS` in order) as ``(block, first, data)``."""
    i0 = grid_index(chainage_m)
    n = int(chainage_m.size)
    out = []
    at = 0
    while at < n:
        i = i0 + at
        block = i // BLOCK_POINTS
        end = min(n, (block + 1) * BLOCK_POINTS - i0)
        out.append((block, i, encode_block([c[at:end] for c in columns], SCALES)))
        at = end
    return out


def insert_profile(
    session: Session,
    run_id: int,
    chainage_m: NDArray[np.float64],
    front_level_mm: NDArray[np.float64],
    rear_level_mm: NDArray[np.float64],
    baseline_mm: NDArray[np.float64],
    front_force_n: NDArray[np.float64],
    rear_force_n: NDArray[np.float64],
) -> int:
    """Insert a run's profile (chainage in m on the 0.25 m grid, each axle's level and the
    baseline in mm, each axle's wheel force in N) in the session's transaction; the fused
    level is :func:`~engine.pipeline.fuse_axles` of the axles' levels.

    Returns the number of grid points written.
    """
    columns = [front_level_mm, rear_level_mm, baseline_mm, front_force_n, rear_force_n]
    rows = [
        {"run_id": run_id, "block": b, "first": first, "data": data}
        for b, first, data in encode_profile(np.asarray(chainage_m, dtype=np.float64), columns)
    ]
    if rows:
        session.execute(insert(RunProfileBlock), rows)
    return int(chainage_m.size)


def delete_profile(session: Session, run_id: int) -> int:
    """Remove a run's stored profile (caller commits); the number of blocks removed."""
    res = session.execute(delete(RunProfileBlock).where(RunProfileBlock.run_id == run_id))
    return int(getattr(res, "rowcount", 0) or 0)


def has_profile(session: Session, run_id: int) -> bool:
    """Whether the run has a stored profile."""
    t = RunProfileBlock.__table__
    return (
        session.execute(select(t.c.block).where(t.c.run_id == run_id).limit(1)).first() is not None
    )


def _block_rows(
    session: Session, run_id: int, from_m: float | None, to_m: float | None
) -> list[tuple[int, bytes]]:
    """The ``(first, data)`` of the run's blocks touching the window, in order: one range
    scan of the key, one statement (so one consistent state of the database)."""
    t = RunProfileBlock.__table__
    stmt = select(t.c.first, t.c.data).where(t.c.run_id == run_id)
    if from_m is not None:
        lo = int(np.floor(from_m / GRID_STEP_M - _GRID_TOL)) // BLOCK_POINTS
        stmt = stmt.where(t.c.block >= lo)
    if to_m is not None:
        hi = int(np.ceil(to_m / GRID_STEP_M + _GRID_TOL)) // BLOCK_POINTS
        stmt = stmt.where(t.c.block <= hi)
    return [(int(f), bytes(d)) for f, d in session.execute(stmt.order_by(t.c.block))]


def _decode_window(
    rows: list[tuple[int, bytes]],
    from_m: float | None,
    to_m: float | None,
    columns: tuple[str, ...],
) -> dict[str, NDArray[np.float64]]:
    parts: list[list[NDArray[np.float64]]] = [[] for _ in columns]
    lo_i = -np.inf if from_m is None else from_m / GRID_STEP_M - _GRID_TOL
    hi_i = np.inf if to_m is None else to_m / GRID_STEP_M + _GRID_TOL
    # The stored columns each asked column is made of (the level is the fused axles).
    sources = {
        name: () if name == "chainage_m" else (0, 1) if name == "level_mm" else
        (STORED_COLUMNS.index(name),)
        for name in columns
    }  # fmt: skip
    wanted = sorted({i for src in sources.values() for i in src}) or [0]  # [0]: the block's length
    for first, data in rows:
        decoded = dict(zip(wanted, decode_block(data, SCALES, wanted), strict=True))
        idx = first + np.arange(decoded[wanted[0]].size)
        keep = (idx >= lo_i) & (idx <= hi_i)
        if not keep.any():
            continue
        a, b = int(np.argmax(keep)), int(keep.size - np.argmax(keep[::-1]))
        for j, name in enumerate(columns):
            if name == "chainage_m":
                parts[j].append(idx[a:b].astype(np.float64) * GRID_STEP_M)
            elif name == "level_mm":
                parts[j].append(fuse_axles(decoded[0][a:b], decoded[1][a:b]))
            else:
                parts[j].append(decoded[STORED_COLUMNS.index(name)][a:b])
    return {
        name: (np.concatenate(p) if p else np.empty(0))
        for name, p in zip(columns, parts, strict=True)
    }


def profile_arrays(
    session: Session,
    run_id: int,
    from_m: float | None = None,
    to_m: float | None = None,
    columns: tuple[str, ...] = PROFILE_COLUMNS,
) -> dict[str, NDArray[np.float64]]:
    """A run's stored profile between two chainages (m, inclusive, as stored) as float64
    arrays by column (NaN = no data): one range scan of the block key."""
    return _decode_window(_block_rows(session, run_id, from_m, to_m), from_m, to_m, columns)


def json_columns(arrays: dict[str, NDArray[np.float64]]) -> dict[str, list[Any]]:
    """Columns of :func:`profile_arrays` as JSON-ready lists (missing values as None)."""
    return {
        name: (a.tolist() if name == "chainage_m" else nullable(a)) for name, a in arrays.items()
    }


def profile_blocks(
    session: Session, run_id: int, from_m: float | None = None, to_m: float | None = None
) -> list[tuple[int, bytes]]:
    """The run's stored blocks touching a window (m, as stored), compressed (~20 kB per km),
    for :func:`iter_profile_rows`: fetched with one statement, so what is streamed later is
    one consistent state even while retention removes detail."""
    return _block_rows(session, run_id, from_m, to_m)


def iter_profile_rows(
    rows: list[tuple[int, bytes]],
    from_m: float | None,
    to_m: float | None,
    columns: tuple[str, ...] = PROFILE_COLUMNS,
    batch: int = 20_000,
) -> Iterator[list[tuple[Any, ...]]]:
    """A run's profile rows (the ``columns``, chainage first) from its fetched blocks
    (:func:`profile_blocks`), decoded in batches of about ``batch`` rows."""
    per = max(1, batch // BLOCK_POINTS)
    for at in range(0, len(rows), per):
        cols = _decode_window(rows[at : at + per], from_m, to_m, columns)
        out = [cols[c].tolist() if c == "chainage_m" else nullable(cols[c]) for c in columns]
        batch_rows = list(zip(*out, strict=True))
        if batch_rows:
            yield batch_rows
