"""Geometry vs stiffness (issue 10): wheel force per run, load inputs, reference surveys,
the separated stiffness of each track.

- ``runs``: the load a client declared (``payload_kg`` or ``static_wheel_load_n``), the
  run's mean wheel force and whether its single-pass stiffness figures are valid (the rail
  is smooth at the noise level); NULL for runs processed before this revision.
- ``profile_points``: each axle's wheel force (static + dynamic), N, beside its level.
- ``track_run_levels.force_n``: the wheel force of the aligned level, float32 chunks like it.
- ``surveys`` and ``survey_levels``: reference surveys of a track (known wheel load) and
  their aligned level on the track grid.
- ``track_stiffness`` (per 250 m chunk: geometry, k_rel and its band, ...) and
  ``track_stiffness_spots``: the separation of geometry and stiffness over a track's passes.

Revision ID: 0005
Revises: 0004
Create Date: 2026-12-01
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.base import UTCDateTime

revision: str = "0005"
down_revision: str | Sequence[str] | None = "0004"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("runs") as batch:
        batch.add_column(sa.Column("payload_kg", sa.Float(), nullable=True))
        batch.add_column(sa.Column("static_wheel_load_n", sa.Float(), nullable=True))
        batch.add_column(sa.Column("mean_wheel_force_n", sa.Float(), nullable=True))
        batch.add_column(sa.Column("single_pass_valid", sa.Boolean(), nullable=True))
    with op.batch_alter_table("profile_points") as batch:
        batch.add_column(sa.Column("front_force_n", sa.Float(), nullable=True))
        batch.add_column(sa.Column("rear_force_n", sa.Float(), nullable=True))
    with op.batch_alter_table("track_run_levels") as batch:
        batch.add_column(sa.Column("force_n", sa.LargeBinary(), nullable=True))
    op.create_table(
        "surveys",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=True),
        sa.Column("original_filename", sa.String(length=255), nullable=True),
        sa.Column("recorded_at", UTCDateTime(), nullable=True),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.Column("wheel_load_n", sa.Float(), nullable=False),
        sa.Column("band_min_m", sa.Float(), nullable=False),
        sa.Column("band_max_m", sa.Float(), nullable=False),
        sa.Column("n_points", sa.Integer(), nullable=False),
        sa.Column("chainage_min_m", sa.Float(), nullable=False),
        sa.Column("chainage_max_m", sa.Float(), nullable=False),
        sa.Column("chainage_offset_m", sa.Float(), nullable=False),
        sa.Column("alignment_status", sa.String(length=12), nullable=False),
        sa.Column("alignment_correlation", sa.Float(), nullable=True),
        sa.Column("alignment_reason", sa.Text(), nullable=True),
        sa.Column("content_hash", sa.String(length=64), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(
            ["track_id"], ["tracks.id"], name=op.f("fk_surveys_track_id_tracks"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.PrimaryKeyConstraint("id", name=op.f("pk_surveys")),
        sa.UniqueConstraint("track_id", "content_hash", name=op.f("uq_surveys_track_id_content_hash")),
        sqlite_autoincrement=True,
    )
    op.create_table(
        "survey_levels",
        sa.Column("survey_id", sa.Integer(), nullable=False),
        sa.Column("chunk", sa.Integer(), autoincrement=False, nullable=False),
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("levels", sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(
            ["survey_id"], ["surveys.id"], name=op.f("fk_survey_levels_survey_id_surveys"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.ForeignKeyConstraint(
            ["track_id"], ["tracks.id"], name=op.f("fk_survey_levels_track_id_tracks"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.PrimaryKeyConstraint("survey_id", "chunk", name=op.f("pk_survey_levels")),
    )
    op.create_index("ix_survey_levels_track_id_chunk", "survey_levels", ["track_id", "chunk"])
    op.create_table(
        "track_stiffness",
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("chunk", sa.Integer(), autoincrement=False, nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.Column("meta", sa.JSON(), nullable=False),
        sa.ForeignKeyConstraint(
            ["track_id"], ["tracks.id"], name=op.f("fk_track_stiffness_track_id_tracks"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.PrimaryKeyConstraint("track_id", "chunk", name=op.f("pk_track_stiffness")),
    )
    op.create_table(
        "track_stiffness_spots",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("start_m", sa.Float(), nullable=False),
        sa.Column("end_m", sa.Float(), nullable=False),
        sa.Column("peak_m", sa.Float(), nullable=False),
        sa.Column("loss_pct", sa.Float(), nullable=False),
        sa.Column("depth_mm", sa.Float(), nullable=True),
        sa.Column("loss_lo_pct", sa.Float(), nullable=True),
        sa.Column("loss_hi_pct", sa.Float(), nullable=True),
        sa.Column("confidence", sa.Float(), nullable=True),
        sa.ForeignKeyConstraint(
            ["track_id"], ["tracks.id"], name=op.f("fk_track_stiffness_spots_track_id_tracks"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.PrimaryKeyConstraint("id", name=op.f("pk_track_stiffness_spots")),
    )
    op.create_index(
        "ix_track_stiffness_spots_track_id_peak_m", "track_stiffness_spots",
        ["track_id", "peak_m"],
    )  # fmt: skip


def downgrade() -> None:
    op.drop_index("ix_track_stiffness_spots_track_id_peak_m", table_name="track_stiffness_spots")
    op.drop_table("track_stiffness_spots")
    op.drop_table("track_stiffness")
    op.drop_index("ix_survey_levels_track_id_chunk", table_name="survey_levels")
    op.drop_table("survey_levels")
    op.drop_table("surveys")
    with op.batch_alter_table("track_run_levels") as batch:
        batch.drop_column("force_n")
    with op.batch_alter_table("profile_points") as batch:
        batch.drop_column("rear_force_n")
        batch.drop_column("front_force_n")
    with op.batch_alter_table("runs") as batch:
        batch.drop_column("single_pass_valid")
        batch.drop_column("mean_wheel_force_n")
        batch.drop_column("static_wheel_load_n")
        batch.drop_column("payload_kg")
