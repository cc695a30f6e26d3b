"""Writing and reading a run's profile: one row per chainage grid point.

Writes go through the DBAPI's ``executemany`` in batches (SQLite takes ~0.5 s for the
432 000 points of a one-hour run at 30 m/s); reads are one range scan of the
``(run_id, chainage_m)`` primary key.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import insert, select
from sqlalchemy.orm import Session

from app.db.models import ProfilePoint

PROFILE_COLUMNS = (
    "chainage_m", "level_mm", "front_level_mm", "rear_level_mm", "baseline_mm",
    "front_force_n", "rear_force_n",
)  # fmt: skip
BATCH_ROWS = 50_000

_PLACEHOLDER = {"qmark": "?", "format": "%s", "pyformat": "%s"}


def nullable(a: NDArray[np.float64]) -> list[float | None]:
    """Values as a list with None where there is no data (NaN, inf): JSON null, SQL NULL."""
    # NaN means "no data here" (an axle that did not pass): stored as NULL on every database.
    values: list[float | None] = a.tolist()
    bad = np.flatnonzero(~np.isfinite(a))
    for i in bad:
        values[i] = None
    return values


def fused_force(front: NDArray[np.float64], rear: NDArray[np.float64]) -> NDArray[np.float64]:
    """The wheel force under the fused level from each axle's (N, same grid): their mean where
    both passed (the fused level is the mean of the axles' levels), else the one that did."""
    both = np.isfinite(front) & np.isfinite(rear)
    return np.where(both, 0.5 * (front + rear), np.where(np.isfinite(front), front, rear))


def insert_profile(
    session: Session,
    run_id: int,
    chainage_m: NDArray[np.float64],
    level_mm: NDArray[np.float64],
    front_level_mm: NDArray[np.float64],
    rear_level_mm: NDArray[np.float64],
    baseline_mm: NDArray[np.float64],
    front_force_n: NDArray[np.float64],
    rear_force_n: NDArray[np.float64],
) -> int:
    """Insert a run's profile (chainage in m, levels in mm, each axle's wheel force in N) in
    the session's transaction.

    Returns the number of rows written.
    """
    n = int(chainage_m.size)
    conn = session.connection()
    mark = _PLACEHOLDER.get(conn.dialect.paramstyle)
    cols = ("run_id", *PROFILE_COLUMNS)
    sql = (
        f"INSERT INTO {ProfilePoint.__tablename__} ({', '.join(cols)}) "
        f"VALUES ({', '.join([mark or ''] * len(cols))})"
    )
    for lo in range(0, n, BATCH_ROWS):
        hi = min(n, lo + BATCH_ROWS)
        columns = [
            chainage_m[lo:hi].tolist(),
            nullable(level_mm[lo:hi]),
            nullable(front_level_mm[lo:hi]),
            nullable(rear_level_mm[lo:hi]),
            nullable(baseline_mm[lo:hi]),
            nullable(front_force_n[lo:hi]),
            nullable(rear_force_n[lo:hi]),
        ]
        if mark is not None:
            rows = list(zip([run_id] * (hi - lo), *columns, strict=True))
            conn.exec_driver_sql(sql, rows)
        else:
            dict_rows = [
                dict(zip(cols, r, strict=True))
                for r in zip([run_id] * (hi - lo), *columns, strict=True)
            ]
            conn.execute(insert(ProfilePoint), dict_rows)
    return n


def read_profile(
    session: Session,
    run_id: int,
    from_m: float | None = None,
    to_m: float | None = None,
    columns: tuple[str, ...] = PROFILE_COLUMNS,
) -> dict[str, list[Any]]:
    """A run's stored profile between two chainages (m, inclusive, as stored), by column.

    Missing values (NULL) come back as None.
    """
    table = ProfilePoint.__table__
    stmt = select(*(table.c[name] for name in columns)).where(table.c.run_id == run_id)
    if from_m is not None:
        stmt = stmt.where(table.c.chainage_m >= from_m)
    if to_m is not None:
        stmt = stmt.where(table.c.chainage_m <= to_m)
    stmt = stmt.order_by(table.c.chainage_m)
    rows = session.execute(stmt).all()
    if not rows:
        return {name: [] for name in columns}
    return {name: list(col) for name, col in zip(columns, zip(*rows, strict=True), strict=True)}


def iter_profile_rows(
    session: Session,
    run_id: int,
    from_m: float | None,
    to_m: float | None,
    columns: tuple[str, ...] = PROFILE_COLUMNS,
    batch: int = 20_000,
) -> Iterator[list[tuple[Any, ...]]]:
    """Stream a run's profile rows (the ``columns``, chainage first) in batches."""
    table = ProfilePoint.__table__
    stmt = select(*(table.c[name] for name in columns)).where(table.c.run_id == run_id)
    if from_m is not None:
        stmt = stmt.where(table.c.chainage_m >= from_m)
    if to_m is not None:
        stmt = stmt.where(table.c.chainage_m <= to_m)
    result = session.execute(stmt.order_by(table.c.chainage_m).execution_options(yield_per=batch))
    for part in result.partitions(batch):
        yield [tuple(r) for r in part]
