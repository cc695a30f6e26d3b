"""Database engine and sessions: SQLite with WAL, foreign keys and a busy timeout by default."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import make_url
from sqlalchemy.orm import Session, sessionmaker

SQLITE_BUSY_TIMEOUT_MS = 30_000
"""How long a SQLite writer waits for another one to finish, ms."""

SQLITE_AUTOCHECKPOINT_PAGES = 65_536
"""WAL pages (4 KiB each: 256 MiB) after which a committing writer copies the WAL into the
database itself. SQLite's default, 1000 pages, made the commit of every hour-long log's input
(~50 MB) do that copy and its fsync on the request's path (+0.35 s of its 0.6 s); the
worker checkpoints when it goes idle instead (:meth:`Database.checkpoint`), and this bound
only applies when it never does."""

SQLITE_JOURNAL_SIZE_LIMIT_B = 64 << 20
"""Size the WAL file is truncated back to after a checkpoint has emptied it, B."""


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    # Per connection: WAL lets readers run while a run is being written; NORMAL sync is
    # durable at each checkpoint and safe in WAL mode; SQLite enforces FKs only when asked.
    if not isinstance(dbapi_connection, sqlite3.Connection):
        return
    cur = dbapi_connection.cursor()
    cur.execute("PRAGMA journal_mode=WAL")
    cur.execute("PRAGMA synchronous=NORMAL")
    cur.execute("PRAGMA foreign_keys=ON")
    cur.execute(f"PRAGMA busy_timeout={SQLITE_BUSY_TIMEOUT_MS}")
    cur.execute(f"PRAGMA wal_autocheckpoint={SQLITE_AUTOCHECKPOINT_PAGES}")
    cur.execute(f"PRAGMA journal_size_limit={SQLITE_JOURNAL_SIZE_LIMIT_B}")
    cur.close()


def sqlite_path(url: str) -> Path | None:
    """The database file of a SQLite URL, or None for other databases (and in-memory SQLite)."""
    u = make_url(url)
    if u.get_backend_name() != "sqlite" or not u.database or u.database == ":memory:":
        return None
    return Path(u.database)


def normalize_url(url: str) -> str:
    """``url`` with PostgreSQL's driver made explicit: ``postgres://`` and ``postgresql://``
    (as Docker images and hosting services write them) become ``postgresql+psycopg://``, the
    driver the service installs (psycopg 3); every other URL is returned unchanged."""
    for prefix in ("postgres://", "postgresql://"):
        if url.startswith(prefix):
            return "postgresql+psycopg://" + url.removeprefix(prefix)
    return url


def make_engine(url: str) -> Engine:
    """An SQLAlchemy engine for ``url``; SQLite files get their directory and pragmas."""
    url = normalize_url(url)
    path = sqlite_path(url)
    if make_url(url).get_backend_name() == "sqlite":
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(
            url,
            connect_args={"check_same_thread": False, "timeout": SQLITE_BUSY_TIMEOUT_MS / 1000},
        )
        event.listen(engine, "connect", _sqlite_pragmas)
        return engine
    return create_engine(url, pool_pre_ping=True)


class Database:
    """An engine and its session factory (one per app instance)."""

    def __init__(self, url: str) -> None:
        self.url = normalize_url(url)
        self.engine = make_engine(url)
        self.session_factory = sessionmaker(bind=self.engine, expire_on_commit=False)

    @property
    def is_sqlite(self) -> bool:
        """True when the database is SQLite."""
        return self.engine.dialect.name == "sqlite"

    @contextmanager
    def session(self) -> Iterator[Session]:
        """A session closed on exit (the caller commits)."""
        with self.session_factory() as session:
            yield session

    def checkpoint(self) -> int:
        """SQLite: copy what the WAL holds into the database file, without waiting for
        readers or blocking writers (a passive checkpoint); returns the pages copied (0 when
        there was nothing to do, and always on other databases)."""
        if not self.is_sqlite:
            return 0
        with self.engine.connect() as conn:
            busy, wal_pages, copied = conn.exec_driver_sql("PRAGMA wal_checkpoint(PASSIVE)").one()
        return int(copied) if wal_pages > 0 else 0

    def dispose(self) -> None:
        """Close every pooled connection."""
        self.engine.dispose()
