"""Vehicles as they really are: parameter versions, calibrations, the version behind each run.

Every existing vehicle gets version 1 (its current parameters, source ``created``); runs
processed before this revision keep ``vehicle_version`` NULL (computed before versions
existed, with version 1's parameters unless the vehicle was edited outside the API).

Revision ID: 0004
Revises: 0003
Create Date: 2026-12-01
"""

from collections.abc import Sequence
from datetime import UTC, datetime

import sqlalchemy as sa
from alembic import op

from app.db.base import UTCDateTime

revision: str = "0004"
down_revision: str | Sequence[str] | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

PARAM_COLUMNS = {
    "ms": "ms", "Is": "pitch_inertia", "mu1": "mu1", "mu2": "mu2", "ks1": "ks1", "ks2": "ks2",
    "cs1": "cs1", "cs2": "cs2", "kt1": "kt1", "kt2": "kt2", "d1": "d1", "d2": "d2",
    "sensor_x_m": "sensor_x_m",
}  # fmt: skip
"""The vehicle parameters as of this revision: name -> column."""


def upgrade() -> None:
    with op.batch_alter_table("vehicles") as batch:
        batch.add_column(
            sa.Column("version", sa.Integer(), nullable=False, server_default=sa.text("1"))
        )
    with op.batch_alter_table("runs") as batch:
        batch.add_column(sa.Column("vehicle_version", sa.Integer(), nullable=True))
    versions = op.create_table(
        "vehicle_versions",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("vehicle_id", sa.Integer(), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("params", sa.JSON(), nullable=False),
        sa.Column("source", sa.String(length=20), nullable=False),
        sa.Column("calibration_id", sa.Integer(), nullable=True),
        sa.Column("created_by", sa.String(length=200), nullable=True),
        sa.Column("note", sa.Text(), nullable=True),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.ForeignKeyConstraint(
            ["vehicle_id"], ["vehicles.id"], name=op.f("fk_vehicle_versions_vehicle_id_vehicles"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.PrimaryKeyConstraint("id", name=op.f("pk_vehicle_versions")),
        sa.UniqueConstraint(
            "vehicle_id", "version", name=op.f("uq_vehicle_versions_vehicle_id_version")
        ),
    )
    op.create_table(
        "calibrations",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("vehicle_id", sa.Integer(), nullable=False),
        sa.Column("status", sa.String(length=12), nullable=False),
        sa.Column("request", sa.JSON(), nullable=False),
        sa.Column("result", sa.JSON(), nullable=True),
        sa.Column("error", sa.JSON(), nullable=True),
        sa.Column("applied", sa.Boolean(), nullable=False),
        sa.Column("applied_version", sa.Integer(), nullable=True),
        sa.Column("automatic", sa.Boolean(), nullable=False),
        sa.Column("created_by", sa.String(length=200), nullable=True),
        sa.Column("runs_from", UTCDateTime(), nullable=True),
        sa.Column("runs_to", UTCDateTime(), nullable=True),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.Column("finished_at", UTCDateTime(), nullable=True),
        sa.Column("claimed_by", sa.String(length=120), nullable=True),
        sa.Column("heartbeat_at", UTCDateTime(), nullable=True),
        sa.Column("attempts", sa.Integer(), nullable=False),
        sa.ForeignKeyConstraint(
            ["vehicle_id"], ["vehicles.id"], name=op.f("fk_calibrations_vehicle_id_vehicles"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.PrimaryKeyConstraint("id", name=op.f("pk_calibrations")),
        sqlite_autoincrement=True,
    )
    op.create_index(
        op.f("ix_calibrations_vehicle_id"), "calibrations", ["vehicle_id"], unique=False
    )
    op.create_index(
        "ix_calibrations_status_heartbeat_at", "calibrations", ["status", "heartbeat_at"]
    )
    cols = ", ".join(PARAM_COLUMNS.values())
    rows = op.get_bind().execute(sa.text(f"SELECT id, {cols} FROM vehicles")).all()
    now = datetime.now(UTC)
    op.bulk_insert(
        versions,
        [
            {
                "vehicle_id": r[0], "version": 1, "source": "created", "created_at": now,
                "params": {name: float(v) for name, v in zip(PARAM_COLUMNS, r[1:], strict=True)},
            }
            for r in rows
        ],
    )  # fmt: skip


def downgrade() -> None:
    op.drop_index("ix_calibrations_status_heartbeat_at", table_name="calibrations")
    op.drop_index(op.f("ix_calibrations_vehicle_id"), table_name="calibrations")
    op.drop_table("calibrations")
    op.drop_table("vehicle_versions")
    with op.batch_alter_table("runs") as batch:
        batch.drop_column("vehicle_version")
    with op.batch_alter_table("vehicles") as batch:
        batch.drop_column("version")
