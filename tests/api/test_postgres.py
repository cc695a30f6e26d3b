"""PostgreSQL: the same app and the same migrations behind ``DATABASE_URL``.

The whole API suite runs on PostgreSQL when ``TEST_DATABASE_URL`` is set (``scripts/test.sh``
starts a throwaway server and does so); the tests here check what only matters there: URLs as
deployments write them, several processes migrating one database at once, and a schema
identical to SQLite's.
"""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest
from sqlalchemy import create_engine, inspect
from sqlalchemy.engine import make_url
from sqlalchemy.pool import NullPool

from api.api_support import row_counts, sql, stored_points
from api.live_server import live_servers
from app.core.config import Settings
from app.db.migrate import alembic_config, upgrade
from app.db.session import Database, normalize_url


def test_driverless_postgres_urls_use_psycopg() -> None:
    """``postgres://`` and ``postgresql://`` (as Docker images write them) select psycopg 3;
    other URLs are kept as given."""
    assert normalize_url("postgres://u:p@db:5432/tp") == "postgresql+psycopg://u:p@db:5432/tp"
    assert normalize_url("postgresql://db/tp") == "postgresql+psycopg://db/tp"
    assert normalize_url("postgresql+psycopg://db/tp") == "postgresql+psycopg://db/tp"
    assert normalize_url("sqlite:////data/x.db") == "sqlite:////data/x.db"


def _schema(url: str) -> dict[str, dict[str, object]]:
    engine = create_engine(normalize_url(url), poolclass=NullPool)
    try:
        insp = inspect(engine)
        return {
            table: {
                "columns": sorted(c["name"] for c in insp.get_columns(table)),
                "primary_key": insp.get_pk_constraint(table)["constrained_columns"],
                "foreign_keys": sorted(
                    (tuple(fk["constrained_columns"]), fk["referred_table"])
                    for fk in insp.get_foreign_keys(table)
                ),
                "unique": sorted(
                    tuple(u["column_names"]) for u in insp.get_unique_constraints(table)
                ),
                # PostgreSQL also lists the index behind each unique constraint
                "indexes": sorted(
                    (tuple(i["column_names"]), bool(i["unique"]))
                    for i in insp.get_indexes(table)
                    if "duplicates_constraint" not in i
                ),
            }
            for table in insp.get_table_names()
        }
    finally:
        engine.dispose()


@pytest.mark.postgres
def test_migrations_give_postgres_the_same_schema_as_sqlite(settings, tmp_path: Path) -> None:
    """Tables, columns, keys and indexes after the migrations are the same on PostgreSQL as on
    SQLite, and the downgrade to nothing works there too."""
    from alembic import command

    pg = Database(settings.sqlalchemy_url)
    lite = Database(f"sqlite:///{tmp_path / 'compare.db'}")
    upgrade(pg)
    upgrade(lite)
    assert _schema(pg.url) == _schema(lite.url)
    cfg = alembic_config()
    with pg.engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.downgrade(cfg, "base")
    assert [t for t in _schema(pg.url) if t != "alembic_version"] == []
    pg.dispose()
    lite.dispose()


@pytest.mark.postgres
def test_processes_starting_together_migrate_once(settings: Settings) -> None:
    """Three app processes started at the same moment on an empty database all come up
    healthy (the migrations run under an advisory lock), with the schema at head and the
    Table 1 vehicle seeded once."""
    from alembic.script import ScriptDirectory

    with live_servers(settings, count=3) as servers:
        for s in servers:
            health = httpx.get(s.url + "/healthz", timeout=10).json()
            assert health["database"] == "ok", health
    head = ScriptDirectory.from_config(alembic_config()).get_current_head()
    assert sql(settings, "SELECT version_num FROM alembic_version") == [(head,)]
    assert row_counts(settings)["vehicles"] == 1


@pytest.mark.postgres
def test_service_runs_on_a_driverless_url(settings: Settings, synthetic_run) -> None:
    """A server given ``DATABASE_URL=postgresql://...`` (no driver named) stores an upload on
    PostgreSQL and serves it back."""
    url = make_url(settings.sqlalchemy_url).set(drivername="postgresql")
    plain = settings.model_copy(update={"database_url": url.render_as_string(False)})
    with live_servers(plain) as [server], httpx.Client(base_url=server.url, timeout=60) as c:
        r = c.post(
            "/api/v1/runs",
            files={"file": ("run.csv", synthetic_run["csv"], "text/csv")},
            data={"track": "pg", "start_chainage_m": "12"},
        )
        assert r.status_code == 201, r.text
        profile = c.get(f"/api/v1/runs/{r.json()['id']}/profile").json()
    stored = sum(stored_points(settings).values())
    assert stored == profile["n"] > 400
