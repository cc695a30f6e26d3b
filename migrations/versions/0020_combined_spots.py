"""The soft spots of the combined passes, materialised per aggregate chunk:
``track_profile_chunks.spots``.

A JSON list, one entry per spot of ``engine.accumulate.detect_on_aggregate`` whose deepest
point lies in the chunk: ``start_m``, ``end_m``, ``peak_m`` (m), ``depth_mm``, ``loss_pct``
(null: no figure), ``significance`` and the ids of the runs that ``supporting`` and
``covering`` it. Written when the chunk's aggregate is rebuilt (a run integrated or deleted),
so the register reads it instead of detecting on every request. NULL for chunks stored before:
the register then detects on them as before.

Revision ID: 0020
Revises: 0019
Create Date: 2026-12-03
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0020"
down_revision: str | Sequence[str] | None = "0019"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("track_profile_chunks", sa.Column("spots", sa.JSON(), nullable=True))


def downgrade() -> None:
    op.drop_column("track_profile_chunks", "spots")
