"""Track quality in EN 13848 terms: a track's line speeds and its own quality limits.

``track_line_speeds``: line speed (km/h) per aligned chainage range, picking the speed class
of the isolated-defect limits and the quality classes. ``track_quality_limits``: a track's
isolated-defect limits and class bounds as JSON (no row: the defaults of
``engine.track_quality``).

Revision ID: 0017
Revises: 0010
Create Date: 2026-12-03
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.base import UTCDateTime

revision: str = "0017"
down_revision: str | Sequence[str] | None = "0014"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "track_line_speeds",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("from_m", sa.Float(), nullable=False),
        sa.Column("to_m", sa.Float(), nullable=False),
        sa.Column("speed_kmh", sa.Float(), nullable=False),
        sa.ForeignKeyConstraint(
            ["track_id"],
            ["tracks.id"],
            name=op.f("fk_track_line_speeds_track_id_tracks"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_track_line_speeds")),
    )
    op.create_index("ix_track_line_speeds_track_id", "track_line_speeds", ["track_id"])
    op.create_table(
        "track_quality_limits",
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("data", sa.JSON(), nullable=False),
        sa.Column("updated_at", UTCDateTime(), nullable=False),
        sa.ForeignKeyConstraint(
            ["track_id"],
            ["tracks.id"],
            name=op.f("fk_track_quality_limits_track_id_tracks"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("track_id", name=op.f("pk_track_quality_limits")),
    )


def downgrade() -> None:
    op.drop_table("track_quality_limits")
    op.drop_index("ix_track_line_speeds_track_id", table_name="track_line_speeds")
    op.drop_table("track_line_speeds")
