"""Vehicles: the accelerometer's position from the body CG (``sensor_x_m``, m, default 0).

Vehicles registered before this revision keep the engine's old assumption: the accelerometer
at the centre of gravity (0 m).

Revision ID: 0003
Revises: 0002
Create Date: 2026-12-01
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0003"
down_revision: str | Sequence[str] | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("vehicles") as batch:
        batch.add_column(
            sa.Column("sensor_x_m", sa.Float(), nullable=False, server_default=sa.text("0"))
        )


def downgrade() -> None:
    with op.batch_alter_table("vehicles") as batch:
        batch.drop_column("sensor_x_m")
