"""Fixtures of the service and HTTP tests: the real app on a real database per test.

Every test gets its own database; the app is built with ``create_app(settings)`` and driven
through Starlette's httpx-based test client, which runs the app's lifespan (migrations, the
background worker) like uvicorn does.

With ``TEST_DATABASE_URL`` set to a PostgreSQL URL (``postgresql+psycopg://user@host:port/db``,
see ``scripts/test_postgres.sh``) every test gets a fresh PostgreSQL database on that server
instead (created from the URL's connection, dropped after the test); tests marked
``sqlite_only`` are skipped then and tests marked ``postgres`` run.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import OperationalError
from sqlalchemy.pool import NullPool

from app.core.config import REPO_ROOT, Settings
from app.db.migrate import upgrade
from app.db.session import Database, sqlite_path
from app.main import create_app

with warnings.catch_warnings():
    # Starlette announces a move to httpx2 for its test client; httpx is what is installed.
    warnings.simplefilter("ignore")
    from starlette.testclient import TestClient


TEST_DATABASE_URL = os.environ.get("TEST_DATABASE_URL") or None
"""A PostgreSQL server to run the API tests on (a database per test), or None for SQLite."""

_created_databases: list[str] = []


def uses_postgres() -> bool:
    """True when the API tests run against PostgreSQL (``TEST_DATABASE_URL``)."""
    return TEST_DATABASE_URL is not None and make_url(TEST_DATABASE_URL).get_backend_name() == (
        "postgresql"
    )


def _admin_execute(statement: str) -> None:
    assert TEST_DATABASE_URL is not None
    engine = create_engine(TEST_DATABASE_URL, poolclass=NullPool, isolation_level="AUTOCOMMIT")
    try:
        with engine.connect() as conn:
            conn.execute(text(statement))
    finally:
        engine.dispose()


_TEMPLATE_DATABASE = "tp_template_" + str(os.getpid())
"""PostgreSQL: a database migrated to head once per session, copied for each test's app."""

_template_made: list[str] = []
_template_sqlite: Path | None = None


def _migrated_template() -> str:
    """The URL of a database migrated to head once per session (created on first use): a
    test's app then starts from a copy of it instead of running every migration again."""
    global _template_sqlite
    if uses_postgres():
        assert TEST_DATABASE_URL is not None
        url = make_url(TEST_DATABASE_URL).set(database=_TEMPLATE_DATABASE)
        if not _template_made:
            _admin_execute(f'CREATE DATABASE "{_TEMPLATE_DATABASE}"')
            _template_made.append(_TEMPLATE_DATABASE)
            _migrate(url.render_as_string(hide_password=False))
        return url.render_as_string(hide_password=False)
    if _template_sqlite is None:
        directory = Path(tempfile.mkdtemp(prefix="trackprofile-template-"))
        path = directory / "template.db"
        _migrate(f"sqlite:///{path}")
        _template_sqlite = path
    return f"sqlite:///{_template_sqlite}"


def _migrate(url: str) -> None:
    db = Database(url)
    try:
        upgrade(db)
    finally:
        db.dispose()


def database_url_for(tmp_path: Path, *, migrated: bool = False) -> str:
    """The database of the test that owns ``tmp_path``: a SQLite file in it, or (with
    ``TEST_DATABASE_URL``) a PostgreSQL database named after it, created on first use.

    It is created empty, or with ``migrated`` as a copy of a database migrated to head (what
    the app's start-up would make of an empty one, without running the migrations per test).
    """
    if not uses_postgres():
        path = tmp_path / "trackprofile.db"
        if migrated and not path.exists():
            template = sqlite_path(_migrated_template())
            assert template is not None
            shutil.copyfile(template, path)
        return f"sqlite:///{path}"
    assert TEST_DATABASE_URL is not None
    name = "tp_" + hashlib.sha1(str(tmp_path).encode()).hexdigest()[:24]
    if name not in _created_databases:
        if migrated:
            template = make_url(_migrated_template()).database
            _admin_execute(f'CREATE DATABASE "{name}" TEMPLATE "{template}"')
        else:
            _admin_execute(f'CREATE DATABASE "{name}"')
        _created_databases.append(name)
    return make_url(TEST_DATABASE_URL).set(database=name).render_as_string(hide_password=False)


@pytest.fixture(autouse=True)
def _drop_test_databases() -> Iterator[None]:
    """Drop the PostgreSQL databases a test created once nothing uses them: a test's own
    database after its apps have stopped; one that a module-scoped fixture's app still holds
    open is left to the end of the session."""
    before = len(_created_databases)
    yield
    for name in _created_databases[before:]:
        try:
            _admin_execute(f'DROP DATABASE IF EXISTS "{name}"')
        except OperationalError:  # still in use (a module's app): dropped at the end
            continue
        _created_databases.remove(name)


@pytest.fixture(scope="session", autouse=True)
def _drop_remaining_test_databases() -> Iterator[None]:
    """At the end of the session, drop every test database that is left."""
    yield
    while _created_databases:
        _admin_execute(f'DROP DATABASE IF EXISTS "{_created_databases.pop()}" WITH (FORCE)')
    while _template_made:
        _admin_execute(f'DROP DATABASE IF EXISTS "{_template_made.pop()}" WITH (FORCE)')
    if _template_sqlite is not None:
        shutil.rmtree(_template_sqlite.parent, ignore_errors=True)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Skip ``sqlite_only`` tests on PostgreSQL and ``postgres`` tests on SQLite."""
    pg = uses_postgres()
    skip_sqlite = pytest.mark.skip(reason="checks SQLite specifics (TEST_DATABASE_URL is set)")
    skip_pg = pytest.mark.skip(reason="needs PostgreSQL: set TEST_DATABASE_URL")
    for item in items:
        if pg and "sqlite_only" in item.keywords:
            item.add_marker(skip_sqlite)
        if not pg and "postgres" in item.keywords:
            item.add_marker(skip_pg)


def make_settings(tmp_path: Path, **overrides: Any) -> Settings:
    """Settings for a test app whose database is ``tmp_path/trackprofile.db`` (or, with
    ``TEST_DATABASE_URL``, a PostgreSQL database of its own)."""
    values: dict[str, Any] = {
        "data_dir": tmp_path,
        "database_url": database_url_for(tmp_path, migrated=True),
        "static_dir": REPO_ROOT / "static",
        "poll_interval_s": 0.05,
        # A full collection per app start (~0.3 s in a test process) adds minutes to the
        # suite; test_lifespan checks the freeze itself.
        "freeze_startup_heap": False,
        # Memory handed back after each run (the allocator's defaults): the memory tests
        # measure what a run holds, not what an earlier test's app kept.
        "memory_release_idle_s": 0,
    }
    values.update(overrides)
    return Settings(**values)


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    """Default test settings (short logs processed inline, worker running)."""
    return make_settings(tmp_path)


@pytest.fixture
def client(settings: Settings) -> Iterator[TestClient]:
    """A client of a freshly started app on an empty database."""
    with TestClient(create_app(settings)) as c:
        yield c


@pytest.fixture
def start_app(tmp_path: Path) -> Iterator[Callable[..., TestClient]]:
    """Start apps with custom settings on the test's database: ``start_app(**settings)``."""
    clients: list[TestClient] = []

    def start(**overrides: Any) -> TestClient:
        c = TestClient(create_app(make_settings(tmp_path, **overrides)))
        c.__enter__()
        clients.append(c)
        return c

    yield start
    for c in reversed(clients):
        c.__exit__(None, None, None)


@pytest.fixture(scope="session")
def synthetic_run() -> dict[str, Any]:
    """A short noisy run made with the engine's forward model (independent of ../shared).

    160 m of track with one 50 % soft zone at 70-75 m, 25 m/s, realistic sensor, seed 3.
    Returns the canonical CSV bytes, the start chainage (m) and the true zones.
    """
    import io

    from engine.logio import write_run_csv
    from engine.synthetic import REALISTIC_SENSOR, make_run
    from engine.track import SoftZone

    zones = [SoftZone(70.0, 75.0, 0.5)]
    run = make_run(
        length=160.0, zones=zones, speed=25.0, start_chainage_m=12.0, jitter=0.03,
        sensor=REALISTIC_SENSOR, seed=3,
    )  # fmt: skip
    buf = io.StringIO()
    write_run_csv(run.log, buf, digits=8)
    return {
        "csv": buf.getvalue().encode(),
        "start_chainage_m": 12.0,
        "zones": [{"start_m": z.start_m, "end_m": z.end_m} for z in zones],
        "n_samples": run.log.n,
    }
