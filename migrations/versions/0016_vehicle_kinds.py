"""Vehicle kinds: a vehicle is a half car (its parameters in the columns, as before) or a
bogie vehicle (issue 32).

``vehicles.kind``: the engine's vehicle kind (``engine.vehicle_kinds.VEHICLE_KINDS``),
``half_car`` for every existing vehicle. ``vehicles.kind_params``: the parameters of a kind
other than the half car, as its datasheet gives them (JSON, SI, with ``kind``); NULL for a
half car. A bogie vehicle's half-car columns hold its lumped half car (each bogie one axle),
so that the columns stay filled.

Revision ID: 0016
Revises: 0010
Create Date: 2026-12-03
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0016"
down_revision: str | Sequence[str] | None = "0018"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column(
        "vehicles",
        sa.Column("kind", sa.String(20), nullable=False, server_default="half_car"),
    )
    op.add_column("vehicles", sa.Column("kind_params", sa.JSON(), nullable=True))


def downgrade() -> None:
    op.drop_column("vehicles", "kind_params")
    op.drop_column("vehicles", "kind")
