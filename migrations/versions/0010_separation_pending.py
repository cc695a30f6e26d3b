"""A track's separation redone after its run is done (issue 15): the chunks waiting for it.

``tracks.separation_pending_lo`` / ``separation_pending_hi``: the range of chunks
(``app.services.track.aggregate.CHUNK_POINTS`` grid points each) whose geometry/stiffness
separation a worker is to redo, set in the transaction that stores a queued run's result and
cleared in the one that redoes it (``app.services.track.separation_store.separate_pending``). NULL for
every existing track: their separation is up to date.

Revision ID: 0010
Revises: 0009
Create Date: 2026-12-02
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0010"
down_revision: str | Sequence[str] | None = "0009"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("tracks", sa.Column("separation_pending_lo", sa.Integer(), nullable=True))
    op.add_column("tracks", sa.Column("separation_pending_hi", sa.Integer(), nullable=True))


def downgrade() -> None:
    # ALTER TABLE ... DROP COLUMN (SQLite >= 3.35), not a batch copy of the table: "tracks" is
    # referenced by runs without ON DELETE CASCADE, so dropping the old copy would fail
    op.drop_column("tracks", "separation_pending_hi")
    op.drop_column("tracks", "separation_pending_lo")
