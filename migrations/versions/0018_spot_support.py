"""The passes behind a separated soft spot: ``track_stiffness_spots.support``.

A JSON list of ``{"kind": "run"|"survey", "id": int, "force_n": float}``, one entry per pass
with data over the spot's extent, written with the spot by the separation. The register
counts them as the defect's evidence (passes and distinct wheel loads) and takes the earliest
as its first sighting. NULL for spots stored before: the register then counts the passes of
the spot's chunk.

Revision ID: 0018
Revises: 0010
Create Date: 2026-12-03
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0018"
down_revision: str | Sequence[str] | None = "0017"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("track_stiffness_spots", sa.Column("support", sa.JSON(), nullable=True))


def downgrade() -> None:
    op.drop_column("track_stiffness_spots", "support")
