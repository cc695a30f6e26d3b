"""A run answered done before its long level is stored: ``runs.long_level_pending``.

The queued path stores a run's result and answers it done, then inverts the long level D2 is
filtered from (``engine.track_quality.long_level``) and writes it into the run's
``track_run_levels.long_mm`` in a transaction of its own. Until then the run is marked: the
quality answer says D2 leaves it out, and a worker's idle look computes it again from the
stored log when the process stopped in between. False for every run stored before.

Revision ID: 0024
Revises: 0021
Create Date: 2026-12-03
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0024"
down_revision: str | Sequence[str] | None = "0021"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column(
        "runs",
        sa.Column("long_level_pending", sa.Boolean(), nullable=False, server_default=sa.false()),
    )


def downgrade() -> None:
    # ALTER TABLE ... DROP COLUMN (SQLite >= 3.35), not a batch copy: "runs" is referenced
    # by other tables
    op.drop_column("runs", "long_level_pending")
