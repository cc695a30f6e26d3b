"""Track intelligence: run alignment state, aligned run levels, aggregated track profile,
per-track limits.

Runs processed before this revision keep ``alignment_status`` NULL (never aligned): they stay
out of the aggregate and the register until they are aligned again.

Revision ID: 0002
Revises: 0001
Create Date: 2025-11-24
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.base import UTCDateTime

revision: str = "0002"
down_revision: str | Sequence[str] | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("runs") as batch:
        batch.add_column(sa.Column("alignment_status", sa.String(length=12), nullable=True))
        batch.add_column(sa.Column("alignment_correlation", sa.Float(), nullable=True))
        batch.add_column(sa.Column("alignment_overlap_m", sa.Float(), nullable=True))
        batch.add_column(sa.Column("alignment_reason", sa.Text(), nullable=True))
    op.create_table(
        "track_run_levels",
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("chunk", sa.Integer(), autoincrement=False, nullable=False),
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("levels", sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(
            ["run_id"],
            ["runs.id"],
            name=op.f("fk_track_run_levels_run_id_runs"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["track_id"],
            ["tracks.id"],
            name=op.f("fk_track_run_levels_track_id_tracks"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("run_id", "chunk", name=op.f("pk_track_run_levels")),
    )
    op.create_index("ix_track_run_levels_track_id_chunk", "track_run_levels", ["track_id", "chunk"])
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
        ),
        sa.PrimaryKeyConstraint("track_id", "chainage_m", name=op.f("pk_track_profile_points")),
        sqlite_with_rowid=False,
    )
    op.create_table(
        "track_limits",
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("alert_depth_mm", sa.Float(), nullable=True),
        sa.Column("intervention_depth_mm", sa.Float(), nullable=True),
        sa.Column("immediate_depth_mm", sa.Float(), nullable=True),
        sa.Column("alert_loss_pct", sa.Float(), nullable=True),
        sa.Column("intervention_loss_pct", sa.Float(), nullable=True),
        sa.Column("immediate_loss_pct", sa.Float(), nullable=True),
        sa.Column("updated_at", UTCDateTime(), nullable=False),
        sa.ForeignKeyConstraint(
            ["track_id"],
            ["tracks.id"],
            name=op.f("fk_track_limits_track_id_tracks"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("track_id", name=op.f("pk_track_limits")),
    )


def downgrade() -> None:
    op.drop_table("track_limits")
    op.drop_table("track_profile_points")
    op.drop_index("ix_track_run_levels_track_id_chunk", table_name="track_run_levels")
    op.drop_table("track_run_levels")
    with op.batch_alter_table("runs") as batch:
        batch.drop_column("alignment_reason")
        batch.drop_column("alignment_overlap_m")
        batch.drop_column("alignment_correlation")
        batch.drop_column("alignment_status")
