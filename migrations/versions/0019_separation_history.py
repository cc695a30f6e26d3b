"""The history of a track's separations: ``track_separation_history``.

One row per successive separation of a soft spot (extent and peak in aligned chainage, m;
loss and its band, %; depth at the separation's reference wheel load, mm), with the passes
behind it (``support``, as ``track_stiffness_spots.support``) and those it opened with
(``base``). The register takes a separated defect's trend and first sighting from it. Empty
after the upgrade: a track's history starts with its next separation (its current spots
stand for the first entry until then).

Revision ID: 0019
Revises: 0016
Create Date: 2026-12-03
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.base import UTCDateTime

revision: str = "0019"
down_revision: str | Sequence[str] | None = "0016"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "track_separation_history",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column(
            "track_id",
            sa.Integer(),
            sa.ForeignKey("tracks.id", ondelete="CASCADE"),
            nullable=False,
        ),  # fmt: skip
        sa.Column("start_m", sa.Float(), nullable=False),
        sa.Column("end_m", sa.Float(), nullable=False),
        sa.Column("peak_m", sa.Float(), nullable=False),
        sa.Column("loss_pct", sa.Float(), nullable=False),
        sa.Column("depth_mm", sa.Float(), nullable=True),
        sa.Column("loss_lo_pct", sa.Float(), nullable=True),
        sa.Column("loss_hi_pct", sa.Float(), nullable=True),
        sa.Column("support", sa.JSON(), nullable=False),
        sa.Column("base", sa.JSON(), nullable=False),
        sa.Column("separated_at", UTCDateTime(), nullable=False),
    )
    op.create_index(
        "ix_track_separation_history_track_id_peak_m",
        "track_separation_history",
        ["track_id", "peak_m"],
    )


def downgrade() -> None:
    op.drop_index(
        "ix_track_separation_history_track_id_peak_m", table_name="track_separation_history"
    )
    op.drop_table("track_separation_history")
