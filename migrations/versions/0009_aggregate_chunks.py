"""The aggregated track profile in chunks (issue 15): one row per 250 m, not per 0.25 m.

``track_profile_chunks`` holds a track's aggregate (median level, spread, run count per grid
point) packed per chunk of ``CHUNK_POINTS`` grid points — the chunks of ``track_run_levels``
it is computed from (``app.services.track.aggregate.pack_chunk``: float64, compressed) — replacing
``track_profile_points``, a row per 0.25 m grid point, whose writing was most of the time a
long run spends being stored. Every stored aggregate is moved (the values bit for bit), then
the old table dropped. Downgrade moves them back.

Revision ID: 0009
Revises: 0008
Create Date: 2026-12-01
"""

from collections.abc import Iterator, Sequence
from itertools import groupby

import numpy as np
import sqlalchemy as sa
from alembic import op

revision: str = "0009"
down_revision: str | Sequence[str] | None = "0008"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_POINTS = sa.table(
    "track_profile_points",
    sa.column("track_id", sa.Integer),
    sa.column("chainage_m", sa.Float),
    sa.column("level_mm", sa.Float),
    sa.column("spread_mm", sa.Float),
    sa.column("n_runs", sa.Integer),
)
_CHUNKS = sa.table(
    "track_profile_chunks",
    sa.column("track_id", sa.Integer),
    sa.column("chunk", sa.Integer),
    sa.column("data", sa.LargeBinary),
)


def _point_chunks(
    conn: sa.Connection, track_id: int
) -> Iterator[tuple[int, list[tuple[int, float | None, float | None, int]]]]:
    """A track's aggregate points grouped by chunk: ``(chunk, [(index in the chunk, level,
    spread, n_runs), ...])``, streamed in chainage order."""
    from app.services.track.aggregate import CHUNK_POINTS
    from engine.chainage import GRID_STEP_M

    rows = conn.execute(
        sa.select(_POINTS.c.chainage_m, _POINTS.c.level_mm, _POINTS.c.spread_mm, _POINTS.c.n_runs)
        .where(_POINTS.c.track_id == track_id)
        .order_by(_POINTS.c.chainage_m)
    )
    indexed = ((int(round(c / GRID_STEP_M)), lv, sp, n) for c, lv, sp, n in rows)
    for chunk, part in groupby(indexed, key=lambda r: r[0] // CHUNK_POINTS):
        yield chunk, [(i - chunk * CHUNK_POINTS, lv, sp, n) for i, lv, sp, n in part]


def _nan(v: float | None) -> float:
    return np.nan if v is None else float(v)


def upgrade() -> None:
    from app.services.track.aggregate import CHUNK_POINTS, pack_chunk

    op.create_table(
        "track_profile_chunks",
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("chunk", sa.Integer(), autoincrement=False, nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(
            ["track_id"],
            ["tracks.id"],
            name=op.f("fk_track_profile_chunks_track_id_tracks"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.PrimaryKeyConstraint("track_id", "chunk", name=op.f("pk_track_profile_chunks")),
    )
    conn = op.get_bind()
    tracks = conn.execute(sa.select(_POINTS.c.track_id).distinct()).scalars().all()
    for track_id in tracks:
        rows = []
        for chunk, part in _point_chunks(conn, track_id):
            level, spread = np.full(CHUNK_POINTS, np.nan), np.full(CHUNK_POINTS, np.nan)
            n = np.zeros(CHUNK_POINTS, dtype=np.int64)
            for k, lv, sp, cnt in part:
                level[k], spread[k], n[k] = _nan(lv), _nan(sp), int(cnt)
            rows.append(
                {"track_id": track_id, "chunk": chunk, "data": pack_chunk(level, spread, n)}
            )
            if len(rows) >= 200:
                conn.execute(_CHUNKS.insert(), rows)
                rows = []
        if rows:
            conn.execute(_CHUNKS.insert(), rows)
    op.drop_table("track_profile_points")


def downgrade() -> None:
    from app.services.track.aggregate import CHUNK_POINTS, unpack_chunk
    from engine.chainage import GRID_STEP_M

    op.create_table(
        "track_profile_points",
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("chainage_m", sa.Float(), nullable=False),
        sa.Column("level_mm", sa.Float(), nullable=False),
        sa.Column("spread_mm", sa.Float(), nullable=False),
        sa.Column("n_runs", sa.Integer(), nullable=False),
        sa.ForeignKeyConstraint(
            ["track_id"],
            ["tracks.id"],
            name=op.f("fk_track_profile_points_track_id_tracks"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.PrimaryKeyConstraint("track_id", "chainage_m", name=op.f("pk_track_profile_points")),
        sqlite_with_rowid=False,
    )
    conn = op.get_bind()
    chunks = conn.execute(
        sa.select(_CHUNKS.c.track_id, _CHUNKS.c.chunk, _CHUNKS.c.data).order_by(
            _CHUNKS.c.track_id, _CHUNKS.c.chunk
        )
    ).all()
    for track_id, chunk, blob in chunks:
        level, spread, n = unpack_chunk(blob)
        keep = np.flatnonzero(n > 0)
        grid = (chunk * CHUNK_POINTS + np.arange(CHUNK_POINTS, dtype=np.float64)) * GRID_STEP_M
        rows = [
            {"track_id": track_id, "chainage_m": c, "level_mm": lv, "spread_mm": sp, "n_runs": k}
            for c, lv, sp, k in zip(
                grid[keep].tolist(), level[keep].tolist(), spread[keep].tolist(),
                n[keep].tolist(), strict=True,
            )
        ]  # fmt: skip
        if rows:
            conn.execute(_POINTS.insert(), rows)
    op.drop_table("track_profile_chunks")
