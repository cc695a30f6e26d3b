"""Positions from GNSS (issue 11): track centerlines and how each run was placed.

- ``track_centerlines``: one per track, its vertices (WGS84 lon/lat, chainage per vertex) as
  JSON, with its length and chainage range for listings.
- ``runs.positioning``: the GNSS placement of a run (start chainage, direction, odometer scale,
  residual, fixes used/rejected, lateral offsets); NULL for runs placed by a start chainage.

Revision ID: 0007
Revises: 0006
Create Date: 2026-12-01
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.base import UTCDateTime

revision: str = "0007"
down_revision: str | Sequence[str] | None = "0006"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "track_centerlines",
        sa.Column(
            "track_id",
            sa.Integer(),
            sa.ForeignKey("tracks.id", ondelete="CASCADE"),
            primary_key=True,
        ),
        sa.Column("n_vertices", sa.Integer(), nullable=False),
        sa.Column("length_m", sa.Float(), nullable=False),
        sa.Column("start_chainage_m", sa.Float(), nullable=False),
        sa.Column("end_chainage_m", sa.Float(), nullable=False),
        sa.Column("source", sa.String(20), nullable=False),
        sa.Column("data", sa.JSON(), nullable=False),
        sa.Column("updated_at", UTCDateTime(), nullable=False),
    )
    with op.batch_alter_table("runs") as batch:
        batch.add_column(sa.Column("positioning", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("runs") as batch:
        batch.drop_column("positioning")
    op.drop_table("track_centerlines")
