"""Compact per-run storage and retention (issue 15).

- ``run_profile_blocks``: a run's profile as compressed blocks of 1 km of its 0.25 m grid
  (levels to 0.0001 mm, wheel forces to 1 N; ``app.services.storage.profiles``), replacing the row
  per grid point of ``profile_points``. Every stored profile is moved, then the old table
  dropped.
- ``track_run_levels`` and ``survey_levels``: their float32 chunks compressed losslessly
  (``app.services.storage.packing.pack_f4``).
- ``run_inputs``: each stored log re-packed from an uncompressed ``.npz`` to compressed
  float64 columns, bit for bit (``app.services.run_lifecycle.logs.pack_log``).
- ``run_signals``: the display signals packed (``packed``: time float64, signals float32,
  compressed; ``app.services.views.signals.pack_signals``) instead of JSON lists (``data``).
- ``runs.detail_expired_at``: when retention removed the run's detail (NULL: kept).

The data move uses the service's own codecs, so what it writes is exactly what the service
writes for a new run. Downgrade moves the profiles back (to the stored resolution).

Revision ID: 0008
Revises: 0007
Create Date: 2026-12-01
"""

import io
from collections.abc import Sequence

import numpy as np
import sqlalchemy as sa
from alembic import op

from app.db.base import UTCDateTime

revision: str = "0008"
down_revision: str | Sequence[str] | None = "0007"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_OLD_COLUMNS = (
    "chainage_m", "level_mm", "front_level_mm", "rear_level_mm", "baseline_mm",
    "front_force_n", "rear_force_n",
)  # fmt: skip


def _as_float(values: Sequence[object]) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


def _move_profiles(conn: sa.Connection) -> None:
    from app.services.storage.profiles import STORED_COLUMNS, encode_profile, fuse_axles

    blocks = sa.table(
        "run_profile_blocks",
        sa.column("run_id", sa.Integer),
        sa.column("block", sa.Integer),
        sa.column("first", sa.Integer),
        sa.column("data", sa.LargeBinary),
    )
    run_ids = conn.execute(sa.text("SELECT DISTINCT run_id FROM profile_points")).scalars().all()
    cols = ", ".join(_OLD_COLUMNS)
    for run_id in run_ids:
        rows = conn.execute(
            sa.text(f"SELECT {cols} FROM profile_points WHERE run_id = :r ORDER BY chainage_m"),
            {"r": run_id},
        ).all()
        by_col = dict(zip(_OLD_COLUMNS, zip(*rows, strict=True), strict=True))
        chainage = np.asarray(by_col["chainage_m"], dtype=np.float64)
        values = {name: _as_float(by_col[name]) for name in _OLD_COLUMNS[1:]}
        fused = fuse_axles(values["front_level_mm"], values["rear_level_mm"])
        level = values["level_mm"]
        # The fused level is not stored: it is made from the axles' levels, as the engine did.
        if not np.array_equal(np.isnan(fused), np.isnan(level)) or (
            np.nanmax(np.abs(fused - level), initial=0.0) > 1e-6
        ):
            raise RuntimeError(
                f"run {run_id}: its stored level is not the mean of its axles' levels; "
                "this revision cannot move it without loss"
            )
        encoded = encode_profile(chainage, [values[name] for name in STORED_COLUMNS])
        conn.execute(
            blocks.insert(),
            [{"run_id": run_id, "block": b, "first": f, "data": d} for b, f, d in encoded],
        )


def _pack_chunks(conn: sa.Connection, table: str, key: str, columns: Sequence[str]) -> None:
    from app.services.storage.packing import pack_f4

    for row in conn.execute(sa.text(f"SELECT {key}, chunk FROM {table}")).all():
        values = conn.execute(
            sa.text(f"SELECT {', '.join(columns)} FROM {table} WHERE {key} = :k AND chunk = :c"),
            {"k": row[0], "c": row[1]},
        ).one()
        packed = {
            c: (None if v is None else pack_f4(np.frombuffer(v, dtype="<f4")))
            for c, v in zip(columns, values, strict=True)
        }
        sets = ", ".join(f"{c} = :{c}" for c in columns)
        conn.execute(
            sa.text(f"UPDATE {table} SET {sets} WHERE {key} = :k AND chunk = :c"),
            {**packed, "k": row[0], "c": row[1]},
        )


def _repack_logs(conn: sa.Connection) -> None:
    from app.services.run_lifecycle.logs import LOG_COLUMNS, pack_log
    from engine.runlog import RunLog

    for run_id in conn.execute(sa.text("SELECT run_id FROM run_inputs")).scalars().all():
        data = conn.execute(
            sa.text("SELECT data FROM run_inputs WHERE run_id = :r"), {"r": run_id}
        ).scalar_one()
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {name: z[name] for name in LOG_COLUMNS if name in z.files}
        conn.execute(
            sa.text("UPDATE run_inputs SET data = :d WHERE run_id = :r"),
            {"d": pack_log(RunLog(**arrays)), "r": run_id},
        )


def _pack_signals(conn: sa.Connection) -> None:
    from app.services.views.signals import pack_signals

    for run_id in conn.execute(sa.text("SELECT run_id FROM run_signals")).scalars().all():
        data = conn.execute(
            sa.select(sa.column("data", sa.JSON)).select_from(sa.table("run_signals"))
            .where(sa.column("run_id") == run_id)
        ).scalar_one()  # fmt: skip
        conn.execute(
            sa.text("UPDATE run_signals SET packed = :p WHERE run_id = :r"),
            {"p": pack_signals(data), "r": run_id},
        )


def upgrade() -> None:
    conn = op.get_bind()
    op.create_table(
        "run_profile_blocks",
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("block", sa.Integer(), autoincrement=False, nullable=False),
        sa.Column("first", sa.Integer(), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(
            ["run_id"], ["runs.id"], name=op.f("fk_run_profile_blocks_run_id_runs"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.PrimaryKeyConstraint("run_id", "block", name=op.f("pk_run_profile_blocks")),
    )
    with op.batch_alter_table("runs") as batch:
        batch.add_column(sa.Column("detail_expired_at", UTCDateTime(), nullable=True))
    _move_profiles(conn)
    op.drop_table("profile_points")
    _pack_chunks(conn, "track_run_levels", "run_id", ("levels", "force_n"))
    _pack_chunks(conn, "survey_levels", "survey_id", ("levels",))
    _repack_logs(conn)
    op.add_column("run_signals", sa.Column("packed", sa.LargeBinary(), nullable=True))
    _pack_signals(conn)
    # a plain DROP COLUMN (SQLite >= 3.35), see downgrade()
    op.execute("ALTER TABLE run_signals DROP COLUMN data")


def _unpack_chunks(conn: sa.Connection, table: str, key: str, columns: Sequence[str]) -> None:
    from app.services.storage.packing import unpack_f4

    for row in conn.execute(sa.text(f"SELECT {key}, chunk, {', '.join(columns)} FROM {table}")).all():
        values = {
            c: (None if v is None else unpack_f4(v).astype("<f4").tobytes())
            for c, v in zip(columns, row[2:], strict=True)
        }
        sets = ", ".join(f"{c} = :{c}" for c in columns)
        conn.execute(
            sa.text(f"UPDATE {table} SET {sets} WHERE {key} = :k AND chunk = :c"),
            {**values, "k": row[0], "c": row[1]},
        )


def downgrade() -> None:
    from app.services.run_lifecycle.logs import LOG_COLUMNS, unpack_log
    from app.services.storage.profiles import PROFILE_COLUMNS, json_columns, profile_arrays
    from sqlalchemy.orm import Session

    conn = op.get_bind()
    op.create_table(
        "profile_points",
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("chainage_m", sa.Float(), nullable=False),
        *(sa.Column(c, sa.Float(), nullable=True) for c in _OLD_COLUMNS[1:]),
        sa.ForeignKeyConstraint(
            ["run_id"], ["runs.id"], name=op.f("fk_profile_points_run_id_runs"),
            ondelete="CASCADE",
        ),  # fmt: skip
        sa.PrimaryKeyConstraint("run_id", "chainage_m", name=op.f("pk_profile_points")),
        sqlite_with_rowid=False,
    )
    session = Session(bind=conn)
    points = sa.table("profile_points", sa.column("run_id"), *map(sa.column, _OLD_COLUMNS))
    run_ids = conn.execute(sa.text("SELECT DISTINCT run_id FROM run_profile_blocks")).scalars()
    for run_id in run_ids.all():
        cols = json_columns(profile_arrays(session, run_id, columns=PROFILE_COLUMNS))
        rows = [
            {"run_id": run_id, **dict(zip(PROFILE_COLUMNS, r, strict=True))}
            for r in zip(*(cols[c] for c in PROFILE_COLUMNS), strict=True)
        ]
        if rows:
            conn.execute(points.insert(), rows)
    op.drop_table("run_profile_blocks")
    # A plain DROP COLUMN (SQLite >= 3.35): a batch rebuild of ``runs`` would drop the table
    # and, with foreign keys on, cascade the delete to every run's rows.
    op.execute("ALTER TABLE runs DROP COLUMN detail_expired_at")
    from app.services.views.signals import unpack_signals

    op.add_column("run_signals", sa.Column("data", sa.JSON(), nullable=True))
    signals = sa.table("run_signals", sa.column("run_id"), sa.column("data", sa.JSON))
    for run_id, packed in conn.execute(sa.text("SELECT run_id, packed FROM run_signals")).all():
        conn.execute(
            signals.update().where(signals.c.run_id == run_id),
            {"data": unpack_signals(bytes(packed))},
        )
    op.execute("ALTER TABLE run_signals DROP COLUMN packed")
    _unpack_chunks(conn, "track_run_levels", "run_id", ("levels", "force_n"))
    _unpack_chunks(conn, "survey_levels", "survey_id", ("levels",))
    for run_id in conn.execute(sa.text("SELECT run_id FROM run_inputs")).scalars().all():
        data = conn.execute(
            sa.text("SELECT data FROM run_inputs WHERE run_id = :r"), {"r": run_id}
        ).scalar_one()
        log = unpack_log(data)
        buf = io.BytesIO()
        arrays = {n: getattr(log, n) for n in LOG_COLUMNS if getattr(log, n) is not None}
        np.savez(buf, **arrays)
        conn.execute(
            sa.text("UPDATE run_inputs SET data = :d WHERE run_id = :r"),
            {"d": buf.getvalue(), "r": run_id},
        )
