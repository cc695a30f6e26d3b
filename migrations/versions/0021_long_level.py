"""Each aligned run's loaded level of the long band, D2's own level:
``track_run_levels.long_mm``.

The run inverted a second time with its longest wavelength widened to 100 m
(``engine.track_quality.long_level``), on the same track-grid points as ``levels``, packed by
``app.services.storage.profiles.pack_long_level`` (0.001 mm, first-differenced, Zstandard:
~6 kB per run-km). D2 per EN 13848-1 (25-70 m) is filtered from the passes' median of it.
NULL for runs stored before: their D2 comes from the stored 3-40 m level and the quality
answer flags it (``d2_level`` per section) until the run is processed again.

Revision ID: 0021
Revises: 0020
Create Date: 2026-12-03
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0021"
down_revision: str | Sequence[str] | None = "0020"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("track_run_levels", sa.Column("long_mm", sa.LargeBinary(), nullable=True))


def downgrade() -> None:
    op.drop_column("track_run_levels", "long_mm")
