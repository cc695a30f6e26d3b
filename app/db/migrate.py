"""Apply the Alembic migrations (the app does it on start; ``python -m app.cli migrate`` too).

Several app processes may start at once against one database, so the upgrade runs under a
lock: an exclusive file lock beside a SQLite file, an advisory lock on PostgreSQL.
"""

from __future__ import annotations

import fcntl
from collections.abc import Iterator
from contextlib import contextmanager

from alembic import command
from alembic.config import Config
from sqlalchemy import Connection, text

from app.core.config import REPO_ROOT

from .session import Database, sqlite_path

MIGRATIONS_DIR = REPO_ROOT / "migrations"
_PG_LOCK_ID = 7_243_001


def alembic_config() -> Config:
    """An Alembic config pointing at the project's migrations (no ini file needed)."""
    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    return cfg


@contextmanager
def _file_lock(db: Database) -> Iterator[None]:
    """SQLite: an exclusive lock on a file beside the database, held until the migration's
    transaction has committed (a process that takes it next sees the upgraded schema)."""
    path = sqlite_path(db.url)
    if path is None:
        yield
        return
    lock_path = path.with_name(path.name + ".migrate.lock")
    with open(lock_path, "a+b") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _lock_in_transaction(conn: Connection) -> None:
    """PostgreSQL: an advisory lock released with the transaction (at its commit)."""
    if conn.dialect.name == "postgresql":
        conn.execute(text("SELECT pg_advisory_xact_lock(:k)"), {"k": _PG_LOCK_ID})


def upgrade(db: Database, revision: str = "head") -> None:
    """Bring the database schema up to ``revision`` (idempotent).

    Processes starting together take turns: each upgrades, commits, and only then lets the
    next one look at the schema (which then finds nothing to do).
    """
    cfg = alembic_config()
    with _file_lock(db), db.engine.begin() as conn:
        _lock_in_transaction(conn)
        cfg.attributes["connection"] = conn
        command.upgrade(cfg, revision)


def current_revision(db: Database) -> str | None:
    """The revision the database is at, or None before the first migration."""
    from alembic.runtime.migration import MigrationContext

    with db.engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()
