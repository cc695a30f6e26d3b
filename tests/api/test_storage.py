"""Storage: data survives a restart, migrations, SQLite settings, the per-chainage layout."""

from __future__ import annotations

import sqlite3

import pytest
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError

from api.api_support import db_file, is_sqlite, row_counts, sql, upload
from app.core.config import Settings
from app.db.migrate import alembic_config, current_revision, upgrade
from app.db.models import ProfilePoint
from app.db.session import Database


def test_restart_keeps_the_data(start_app, synthetic_run) -> None:
    """A new app instance on the same database file serves the same runs, profiles and spots."""
    first = start_app()
    rid = upload(first, synthetic_run["csv"], track="T",
                 start_chainage_m=synthetic_run["start_chainage_m"]).json()["id"]  # fmt: skip
    before = {
        p: first.get(f"/api/v1/runs/{rid}{p}").json() for p in ("", "/profile", "/soft-spots")
    }
    first.__exit__(None, None, None)
    second = start_app()
    after = {
        p: second.get(f"/api/v1/runs/{rid}{p}").json() for p in ("", "/profile", "/soft-spots")
    }
    assert after == before
    assert after["/profile"]["n"] > 400


def test_migrations_run_on_start_and_are_idempotent(start_app, settings) -> None:
    """Starting the app brings an empty database to the latest revision; starting again
    changes nothing (the Table 1 vehicle is seeded once)."""
    from alembic.script import ScriptDirectory

    start_app()
    start_app()
    head = ScriptDirectory.from_config(alembic_config()).get_current_head()
    db = Database(settings.sqlalchemy_url)
    assert current_revision(db) == head
    assert row_counts(settings)["vehicles"] == 1
    db.dispose()


def test_migrations_downgrade_and_upgrade(tmp_path) -> None:
    """The migrations can be undone and redone (a broken downgrade would block rollbacks)."""
    from alembic import command

    db = Database(f"sqlite:///{tmp_path / 'm.db'}")
    upgrade(db)
    cfg = alembic_config()
    with db.engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.downgrade(cfg, "base")
    assert current_revision(db) is None
    upgrade(db)
    assert current_revision(db) is not None
    db.dispose()


@pytest.mark.sqlite_only
def test_sqlite_runs_in_wal_mode_with_foreign_keys(client, settings) -> None:
    """The app's connections use WAL, enforce foreign keys and wait on a busy database."""
    ctx = client.app.state.ctx
    with ctx.db.engine.connect() as conn:
        raw = conn.connection.driver_connection
        assert raw.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        assert raw.execute("PRAGMA foreign_keys").fetchone()[0] == 1
        assert raw.execute("PRAGMA busy_timeout").fetchone()[0] >= 5000


@pytest.mark.sqlite_only
def test_profile_is_stored_per_grid_point_and_read_by_key(client, settings, synthetic_run):
    """One row per chainage grid point; a chainage window is a primary-key range search."""
    r = upload(client, synthetic_run["csv"], track="T",
               start_chainage_m=synthetic_run["start_chainage_m"])  # fmt: skip
    rid = r.json()["id"]
    n = client.get(f"/api/v1/runs/{rid}/profile").json()["n"]
    assert row_counts(settings)["profile_points"] == n
    ctx = client.app.state.ctx
    stmt = (
        select(ProfilePoint.chainage_m, ProfilePoint.level_mm)
        .where(ProfilePoint.run_id == rid, ProfilePoint.chainage_m.between(50.0, 60.0))
        .order_by(ProfilePoint.chainage_m)
    )
    sql = str(stmt.compile(ctx.db.engine, compile_kwargs={"literal_binds": True}))
    con = sqlite3.connect(db_file(settings))
    plan = " ".join(str(row[-1]) for row in con.execute(f"EXPLAIN QUERY PLAN {sql}"))
    con.close()
    assert "USING PRIMARY KEY" in plan and "chainage_m>" in plan, plan
    assert "TEMP B-TREE" not in plan  # rows come in chainage order without sorting


def test_nan_levels_are_stored_as_null(client, settings, synthetic_run) -> None:
    """Where an axle did not pass, its level is missing (null), never NaN in the JSON."""
    rid = upload(client, synthetic_run["csv"], track="T",
                 start_chainage_m=synthetic_run["start_chainage_m"]).json()["id"]  # fmt: skip
    prof = client.get(f"/api/v1/runs/{rid}/profile", params={"include": "all"}).json()
    assert None in prof["front_level_mm"] or None in prof["rear_level_mm"]
    nulls = sql(
        settings,
        "SELECT count(*) FROM profile_points WHERE front_level_mm IS NULL OR rear_level_mm IS NULL",
    )[0][0]
    assert nulls > 0


def test_database_location_from_environment(monkeypatch, tmp_path) -> None:
    """DATABASE_URL selects the database; otherwise it is trackprofile.db under
    TRACKPROFILE_DATA_DIR (default ./data)."""
    monkeypatch.delenv("DATABASE_URL", raising=False)
    monkeypatch.setenv("TRACKPROFILE_DATA_DIR", str(tmp_path / "d"))
    assert Settings().sqlalchemy_url == f"sqlite:///{tmp_path / 'd' / 'trackprofile.db'}"
    monkeypatch.setenv("DATABASE_URL", "sqlite:////srv/x.db")
    assert Settings().sqlalchemy_url == "sqlite:////srv/x.db"
    monkeypatch.delenv("TRACKPROFILE_DATA_DIR")
    monkeypatch.delenv("DATABASE_URL")
    assert Settings().sqlalchemy_url.endswith("/data/trackprofile.db")


def test_new_database_directory_is_created(tmp_path) -> None:
    """A data directory that does not exist yet is created with the database."""
    db = Database(f"sqlite:///{tmp_path / 'new' / 'deeper' / 't.db'}")
    upgrade(db)
    assert (tmp_path / "new" / "deeper" / "t.db").is_file()
    db.dispose()


def test_deleting_a_track_with_runs_is_prevented_by_the_database(client, settings) -> None:
    """Foreign keys are enforced: a track with runs cannot be removed underneath them."""
    r = client.post("/api/v1/simulate", json={"track": "fk", "length_m": 120, "zones": [],
                                              "speed_mps": 25})  # fmt: skip
    assert r.status_code == 201, r.text
    if is_sqlite(settings):
        con = sqlite3.connect(db_file(settings))
        con.execute("PRAGMA foreign_keys=ON")
        with pytest.raises(sqlite3.IntegrityError):
            con.execute("DELETE FROM tracks WHERE name='fk'")
        con.close()
    else:
        with pytest.raises(IntegrityError):
            sql(settings, "DELETE FROM tracks WHERE name='fk'")
    assert row_counts(settings)["tracks"] == 1
