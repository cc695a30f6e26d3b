"""What a run could see: its detection limit per zone length.

``runs.detection_limit``: ``engine.results.DetectionLimit.to_dict()`` of the run's last
processing (``zone_length_m``, ``min_loss_pct``, ``threshold_mm``). NULL for runs processed
before it existed, until they are reprocessed.

Revision ID: 0014
Revises: 0010
Create Date: 2026-12-03
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0014"
down_revision: str | Sequence[str] | None = "0010"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("runs", sa.Column("detection_limit", sa.JSON(), nullable=True))


def downgrade() -> None:
    op.drop_column("runs", "detection_limit")
