"""Initial schema: tracks, vehicles (Table 1 seeded), runs, profile points, soft spots,
run inputs and signals, API keys.

Revision ID: 0001
Revises:
Create Date: 2025-11-23
"""

from collections.abc import Sequence
from datetime import UTC, datetime

import sqlalchemy as sa
from alembic import op

from app.db.base import UTCDateTime

revision: str = "0001"
down_revision: str | Sequence[str] | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

# The paper's Table 1 half-car (SI units), frozen here as seed data.
TABLE1 = {
    "ms": 16200.0, "pitch_inertia": 111193.0, "mu1": 700.0, "mu2": 1100.0,
    "ks1": 0.4e6, "ks2": 1.0e6, "cs1": 10e3, "cs2": 20e3, "kt1": 1.75e6, "kt2": 3.5e6,
    "d1": 4.13, "d2": 4.13,
}


def upgrade() -> None:
    op.create_table(
        "tracks",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("description", sa.Text(), nullable=True),
        sa.Column("rail", sa.String(length=50), nullable=False),
        sa.Column("k_nominal", sa.Float(), nullable=False),
        sa.Column("spacing", sa.Float(), nullable=False),
        sa.Column("ei", sa.Float(), nullable=False),
        sa.Column("mass_per_m", sa.Float(), nullable=False),
        sa.Column("c_support", sa.Float(), nullable=False),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_tracks")),
        sa.UniqueConstraint("name", name=op.f("uq_tracks_name")),
    )
    vehicles = op.create_table(
        "vehicles",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("description", sa.Text(), nullable=True),
        sa.Column("ms", sa.Float(), nullable=False),
        sa.Column("pitch_inertia", sa.Float(), nullable=False),
        sa.Column("mu1", sa.Float(), nullable=False),
        sa.Column("mu2", sa.Float(), nullable=False),
        sa.Column("ks1", sa.Float(), nullable=False),
        sa.Column("ks2", sa.Float(), nullable=False),
        sa.Column("cs1", sa.Float(), nullable=False),
        sa.Column("cs2", sa.Float(), nullable=False),
        sa.Column("kt1", sa.Float(), nullable=False),
        sa.Column("kt2", sa.Float(), nullable=False),
        sa.Column("d1", sa.Float(), nullable=False),
        sa.Column("d2", sa.Float(), nullable=False),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_vehicles")),
        sa.UniqueConstraint("name", name=op.f("uq_vehicles_name")),
    )
    op.create_table(
        "runs",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=True),
        sa.Column("track_id", sa.Integer(), nullable=False),
        sa.Column("vehicle_id", sa.Integer(), nullable=False),
        sa.Column("source", sa.String(length=20), nullable=False),
        sa.Column("original_filename", sa.String(length=255), nullable=True),
        sa.Column("recorded_at", UTCDateTime(), nullable=True),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.Column("processed_at", UTCDateTime(), nullable=True),
        sa.Column("start_chainage_m", sa.Float(), nullable=True),
        sa.Column("direction", sa.String(length=12), nullable=False),
        sa.Column("sample_rate_hz", sa.Float(), nullable=False),
        sa.Column("n_samples", sa.Integer(), nullable=False),
        sa.Column("duration_s", sa.Float(), nullable=False),
        sa.Column("speed_min_mps", sa.Float(), nullable=False),
        sa.Column("speed_max_mps", sa.Float(), nullable=False),
        sa.Column("chainage_min_m", sa.Float(), nullable=True),
        sa.Column("chainage_max_m", sa.Float(), nullable=True),
        sa.Column("chainage_offset_m", sa.Float(), nullable=False),
        sa.Column("status", sa.String(length=12), nullable=False),
        sa.Column("stage", sa.String(length=12), nullable=True),
        sa.Column("error", sa.JSON(), nullable=True),
        sa.Column("quality", sa.JSON(), nullable=True),
        sa.Column("method", sa.String(length=20), nullable=True),
        sa.Column("options", sa.JSON(), nullable=False),
        sa.Column("n_soft_spots", sa.Integer(), nullable=True),
        sa.Column("processing_s", sa.Float(), nullable=True),
        sa.Column("content_hash", sa.String(length=64), nullable=False),
        sa.Column("idempotency_key", sa.String(length=200), nullable=True),
        sa.Column("claimed_by", sa.String(length=120), nullable=True),
        sa.Column("heartbeat_at", UTCDateTime(), nullable=True),
        sa.Column("attempts", sa.Integer(), nullable=False),
        sa.ForeignKeyConstraint(
            ["track_id"], ["tracks.id"], name=op.f("fk_runs_track_id_tracks"), ondelete="RESTRICT"
        ),
        sa.ForeignKeyConstraint(
            ["vehicle_id"], ["vehicles.id"], name=op.f("fk_runs_vehicle_id_vehicles"),
            ondelete="RESTRICT",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_runs")),
        sa.UniqueConstraint("idempotency_key", name=op.f("uq_runs_idempotency_key")),
        sa.UniqueConstraint("track_id", "content_hash", name=op.f("uq_runs_track_id_content_hash")),
        sqlite_autoincrement=True,
    )
    op.create_index("ix_runs_track_id_recorded_at", "runs", ["track_id", "recorded_at"])
    op.create_index("ix_runs_status_heartbeat_at", "runs", ["status", "heartbeat_at"])
    op.create_table(
        "run_inputs",
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(
            ["run_id"], ["runs.id"], name=op.f("fk_run_inputs_run_id_runs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("run_id", name=op.f("pk_run_inputs")),
    )
    op.create_table(
        "profile_points",
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("chainage_m", sa.Float(), nullable=False),
        sa.Column("level_mm", sa.Float(), nullable=True),
        sa.Column("front_level_mm", sa.Float(), nullable=True),
        sa.Column("rear_level_mm", sa.Float(), nullable=True),
        sa.Column("baseline_mm", sa.Float(), nullable=True),
        sa.ForeignKeyConstraint(
            ["run_id"], ["runs.id"], name=op.f("fk_profile_points_run_id_runs"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("run_id", "chainage_m", name=op.f("pk_profile_points")),
        sqlite_with_rowid=False,
    )
    op.create_table(
        "soft_spots",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("start_m", sa.Float(), nullable=False),
        sa.Column("end_m", sa.Float(), nullable=False),
        sa.Column("peak_m", sa.Float(), nullable=False),
        sa.Column("depth_mm", sa.Float(), nullable=False),
        sa.Column("stiffness_loss_pct", sa.Float(), nullable=True),
        sa.ForeignKeyConstraint(
            ["run_id"], ["runs.id"], name=op.f("fk_soft_spots_run_id_runs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_soft_spots")),
    )
    op.create_index(op.f("ix_soft_spots_run_id"), "soft_spots", ["run_id"])
    op.create_table(
        "run_signals",
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("n_points", sa.Integer(), nullable=False),
        sa.Column("decimated", sa.Boolean(), nullable=False),
        sa.Column("data", sa.JSON(), nullable=False),
        sa.ForeignKeyConstraint(
            ["run_id"], ["runs.id"], name=op.f("fk_run_signals_run_id_runs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("run_id", name=op.f("pk_run_signals")),
    )
    op.create_table(
        "api_keys",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("prefix", sa.String(length=16), nullable=False),
        sa.Column("key_hash", sa.String(length=64), nullable=False),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.Column("revoked_at", UTCDateTime(), nullable=True),
        sa.Column("last_used_at", UTCDateTime(), nullable=True),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_api_keys")),
        sa.UniqueConstraint("key_hash", name=op.f("uq_api_keys_key_hash")),
    )
    op.bulk_insert(
        vehicles,
        [
            {
                "name": "table1",
                "description": "The paper's Table 1 half-car (the default vehicle)",
                "created_at": datetime.now(UTC),
                **TABLE1,
            }
        ],
    )


def downgrade() -> None:
    op.drop_table("api_keys")
    op.drop_table("run_signals")
    op.drop_index(op.f("ix_soft_spots_run_id"), table_name="soft_spots")
    op.drop_table("soft_spots")
    op.drop_table("profile_points")
    op.drop_table("run_inputs")
    op.drop_index("ix_runs_status_heartbeat_at", table_name="runs")
    op.drop_index("ix_runs_track_id_recorded_at", table_name="runs")
    op.drop_table("runs")
    op.drop_table("vehicles")
    op.drop_table("tracks")
